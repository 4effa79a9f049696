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
        d = d.get(k) if hasattr(d, "keys") else None
    return d


def _range(s, command: str):
    r = _get(s, "selected", "commands", command)
    return None if r is None else [r["p5"], r["p95"]]


# claim id -> where in the summary it is read (keys, or a function of the summary)
def _claims() -> dict:
    c = {
        "budget_evaluations": ("budget_evaluations",),
        "eval_n_targets": ("selected", "n_targets"),
        "eval_arc_deg": ("selected", "arc_deg"),
        "ca_selected_mm": ("selected", "closest_approach_mm"),
        "ca_fixed_mm": ("fixed", "closest_approach_mm"),
        "attach_5cm_selected": ("selected", "attachment"),
        "attach_5cm_fixed": ("fixed", "attachment"),
        "speed_fraction_selected": ("selected", "speed_fraction"),
        "sector_n": lambda s: None if (x := _get(s, "selected", "sectors")) is None else len(x),
        "sector_median_miss_mm": ("selected", "sector_median_range_mm"),
        **{f"cmd_{k}_ticks": (lambda s, k=k: _range(s, k)) for k in ("rho1", "rho2", "rho3", "s3")},
        "cmd_tau_s": lambda s: _range(s, "tau_s"),
        "tau_at_bound_fraction": ("selected", "tau_at_bound_fraction"),
        "reward_p_shared_vs_centralised": ("reward_tests", "centralised", "p"),
        "attach_p_shared_vs_centralised": ("attachment_tests", "centralised", "p"),
        "attach_5cm_best_centralised_seed": ("best_centralised", "attachment"),
    }
    for k in ("rho3_height", "rho3_distance", "rho2_distance", "dphi_height", "tau_distance", "rho3_radius",
              "rho2_radius", "tau_radius", "targets_distance_height"):
        c[f"corr_{k}"] = ("selected", "correlations", k)
    for a in NAMES:
        c[f"n_params_{a}"] = ("n_params", a)
        c[f"seeds_{a}"] = ("reward", a, "n")
        c[f"reward_{a}_mean"] = ("reward", a, "mean")
        c[f"reward_{a}_sd"] = ("reward", a, "sd")
        c[f"attach_5cm_{a}_mean"] = ("attachment_report", a, "mean")
        c[f"attach_5cm_{a}_sd"] = ("attachment_report", a, "sd")
        c[f"reach_{a}_n"] = ("reach", "per_arch", a, "n_reached")
        c[f"reach_{a}_median_evals"] = ("reach", "per_arch", a, "median_evaluations")
        c[f"reach_{a}_median_pct_budget"] = ("reach", "per_arch", a, "median_pct_budget")
    return c


def _ours(a, out) -> None:
    s = a["summary"]
    for cid, how in _claims().items():
        out[cid] = how(s) if callable(how) else _get(s, *how)


def rows(summary, path=None) -> list[dict]:
    """summary: (artifact path, its JSON), or the JSON alone."""
    return claim_rows("policy", _ours, dict(summary=summary), *([path] if path else []))
