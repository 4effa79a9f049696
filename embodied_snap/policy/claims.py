"""Every architecture and generalisation number of sections V-A and V-B (and the IV-B sizes) beside the
paper's: rows of results/policy/claims.csv, read from results/policy/summary.json.
The paper column comes from reference/paper_values.yaml (section `policy`), never from here."""

from __future__ import annotations

from ..reference import claim_rows
from .architectures import NAMES


def _get(d, *keys):
    """d[k1][k2]...; None where any level is missing (e.g. an architecture the budget did not run)."""
    for k in keys:
        if d is None:
            return None
        d = d.get(k) if isinstance(d, dict) else None
    return d


def _range(s: dict, command: str):
    r = _get(s, "selected", "commands", command)
    return None if r is None else [r["p5"], r["p95"]]


def _ours(s: dict) -> dict:
    sectors = _get(s, "selected", "sectors")
    out = {
        "budget_evaluations": s["budget_evaluations"],
        "eval_n_targets": _get(s, "selected", "n_targets"),
        "eval_arc_deg": _get(s, "selected", "arc_deg"),
        "ca_selected_mm": _get(s, "selected", "closest_approach_mm"),
        "ca_fixed_mm": _get(s, "fixed", "closest_approach_mm"),
        "attach_5cm_selected": _get(s, "selected", "attachment"),
        "attach_5cm_fixed": _get(s, "fixed", "attachment"),
        "speed_fraction_selected": _get(s, "selected", "speed_fraction"),
        "sector_n": None if sectors is None else len(sectors),
        "sector_median_miss_mm": _get(s, "selected", "sector_median_range_mm"),
        "cmd_rho1_ticks": _range(s, "rho1"),
        "cmd_rho2_ticks": _range(s, "rho2"),
        "cmd_rho3_ticks": _range(s, "rho3"),
        "cmd_s3_ticks": _range(s, "s3"),
        "cmd_tau_s": _range(s, "tau_s"),
        "tau_at_bound_fraction": _get(s, "selected", "tau_at_bound_fraction"),
        "reward_p_shared_vs_centralised": _get(s, "reward_tests", "centralised", "p"),
        "attach_p_shared_vs_centralised": _get(s, "attachment_tests", "centralised", "p"),
        "attach_5cm_best_centralised_seed": _get(s, "best_centralised", "attachment"),
    }
    for k in ("rho3_height", "rho3_distance", "rho2_distance", "dphi_height", "tau_distance", "rho3_radius",
              "rho2_radius", "tau_radius", "targets_distance_height"):
        out[f"corr_{k}"] = _get(s, "selected", "correlations", k)
    for a in NAMES:
        out[f"n_params_{a}"] = _get(s, "n_params", a)
        out[f"seeds_{a}"] = _get(s, "reward", a, "n")
        out[f"reward_{a}_mean"] = _get(s, "reward", a, "mean")
        out[f"reward_{a}_sd"] = _get(s, "reward", a, "sd")
        out[f"attach_5cm_{a}_mean"] = _get(s, "attachment_report", a, "mean")
        out[f"attach_5cm_{a}_sd"] = _get(s, "attachment_report", a, "sd")
        out[f"reach_{a}_n"] = _get(s, "reach", "per_arch", a, "n_reached")
        out[f"reach_{a}_median_evals"] = _get(s, "reach", "per_arch", a, "median_evaluations")
        out[f"reach_{a}_median_pct_budget"] = _get(s, "reach", "per_arch", a, "median_pct_budget")
    return out


def rows(summary: dict, path=None) -> list[dict]:
    return claim_rows("policy", _ours(summary), *([path] if path else []))
