"""Every section IV-A number beside the paper's: rows of results/dynamics/claims.csv.
The paper column comes from reference/paper_values.yaml (section `dynamics`), never from here."""

from __future__ import annotations

from ..reference import claim_rows


def _seed_range(summaries, key="at_s_mm", at=None):
    v = [s[key][at] for s in summaries]
    return [min(v), max(v)]


def _ours(res, out) -> None:
    val, sealed = res["validation"], res["sealed"]
    seeds = list(sealed["seeds"].values())
    for s in ("0.3", "0.5", "0.7"):
        k = s.replace(".", "p")
        out[f"val_gru_tip_mm_{k}"] = _seed_range(val, at=s)
        out[f"val_persistence_tip_mm_{k}"] = res["persistence"]["at_s_mm"][s]
        out[f"sealed_gru_tip_mm_{k}"] = _seed_range(seeds, at=s)
        out[f"sealed_persistence_tip_mm_{k}"] = sealed["persistence"]["at_s_mm"][s]
    pct = [v for s in seeds for v in s["at_s_pct_arm"].values()]
    out["sealed_gru_pct_arm"] = [min(pct), max(pct)]
    out["sealed_n_windows"] = sealed["persistence"]["n_windows"]
    g = res["gate"]
    out["gate_best_tau_s"] = [v for k, v in sorted(g["best_tau_s"].items()) if k != "measured"]
    out["gate_peak_speed_ratio"] = [min(g["peak_speed_ratio"].values()), max(g["peak_speed_ratio"].values())]
    out["gate_travel_diff_pct"] = [min(g["travel_diff_pct"].values()), max(g["travel_diff_pct"].values())]
    h = res["hold"]
    out["hold_tip_mm"] = h["tip_mm_median"]
    out["hold_tip_pct_arm"] = h["tip_pct_arm_median"]
    out["hold_axis_deg"] = h["axis_deg_median"]


def rows(res: dict, path=None) -> list[dict]:
    """res: persistence, sealed, gate, hold -> (artifact path, its JSON); validation -> a list of them."""
    return claim_rows("dynamics", _ours, res, *([path] if path else []))
