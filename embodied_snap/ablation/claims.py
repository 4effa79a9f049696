"""Every number of the ablation paragraphs (V-A bend point, V-B release rules and perturbation)
beside the paper's: rows of results/ablation/claims.csv from results/ablation/summary.json. The
paper column comes from reference/paper_values.yaml (section `ablation`), never from here."""

from __future__ import annotations

from ..reference import claim_rows


def _ours(a, out) -> None:
    s = a["summary"]
    R = s["rules"]
    out["n_release_targets"] = R["target_only"]["n"]
    out["n_offset_targets"] = s["n_offset_targets"]
    for r in ("target_only", "clock", "s1_rate", "tip_speed", "s2_peak"):
        out[f"attach_5cm_{r}"] = R[r]["attachment"]
    for r in ("s1_rate", "tip_speed", "s2_peak"):
        out[f"mcnemar_p_{r}"] = R[r]["mcnemar"]["p"]
        out[f"at_bound_{r}"] = R[r]["at_bound_fraction"]
    out["bend_n_successes"] = s["bend"]["model"]["n"]
    out["bend_distal_fraction"] = s["bend"]["model"]["distal_fraction"]
    out["bend_mean_correlation"] = s["bend"]["model"]["mean_correlation"]
    P = {round(p["scale"], 3): p for p in s["perturbation"]}
    for sc, key in ((0.0, "0"), (0.5, "0_5"), (1.0, "1"), (1.5, "1_5"), (2.0, "2")):
        p = P.get(sc)
        out[f"perturb_miss_mm_{key}"] = None if p is None else p["median_miss_mm"]
        out[f"perturb_miss_pct_{key}"] = None if p is None else p["median_miss_pct_arm"]
    out["perturb_speed_0"] = P[0.0]["mean_peak_speed"] if 0.0 in P else None
    out["perturb_speed_2"] = P[2.0]["mean_peak_speed"] if 2.0 in P else None


def rows(summary, path=None) -> list[dict]:
    """summary: (artifact path, its JSON), or the JSON alone."""
    return claim_rows("ablation", _ours, dict(summary=summary), *([path] if path else []))
