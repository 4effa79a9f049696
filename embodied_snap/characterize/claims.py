"""Every characterisation number beside the paper's: rows of results/characterize/claims.csv.
The paper column comes from reference/paper_values.yaml (section `characterize`), never from here."""

from __future__ import annotations

from ..reference import claim_rows

# claim id -> (fit artifact, how to read our value from it)
OURS = {
    "tendon_travel_per_tick_um": ("kinematics", lambda r: r["travel_per_tick_um"]["median"]),
    "tendon_travel_per_tick_iqr_um": ("kinematics", lambda r: r["travel_per_tick_um"]["iqr"]),
    "lever_ratio_s1": ("kinematics", lambda r: r["lever_ticks_per_rad"][0]),
    "lever_ratio_s2": ("kinematics", lambda r: r["lever_ticks_per_rad"][1]),
    "lever_ratio_s3": ("kinematics", lambda r: r["lever_ticks_per_rad"][2]),
    "servo_peak_rate_over_rated": ("servo", lambda r: r["peak_rate_over_rated_5_95"]),
    "servo_max_rate_tick_s": ("servo", lambda r: r["rate_tick_s"]),
    "servo_time_constant_s": ("servo", lambda r: r["tau_s"]),
    "servo_n_bursts": ("servo", lambda r: r["n_bursts"]),
    "rate_ceiling_s1": ("servo", lambda r: r["ceiling_rad_s"][0]),
    "rate_ceiling_s2": ("servo", lambda r: r["ceiling_rad_s"][1]),
    "rate_ceiling_s3": ("servo", lambda r: r["ceiling_rad_s"][2]),
    "direct_release_range_mps": ("release", lambda r: r["direct_range_mps"]),
    "attach_below_1mps": ("attachment", lambda r: r["attached_below_1mps"]),
    "attachment_n": ("attachment", lambda r: r["n"]),
    "instant_fraction_over_1mps": ("release", lambda r: r["instant_fraction_over_1mps"]),
    "instant_n": ("release", lambda r: r["instant_n"]),
    "snap_auc": ("snap", lambda r: r["auc_grouped_cv"]),
    "snap_box_fraction_p_gt_0p8": ("snap", lambda r: r["fraction_box_p_gt_0p8"]),
    "operating_tip_speed_mps": ("release", lambda r: r["operating_tip_speed_iqr_mps"]),
    "operating_rate_s1_dps": ("release", lambda r: r["operating_section_rate_dps"][0]),
    "operating_rate_s2_dps": ("release", lambda r: r["operating_section_rate_dps"][1]),
    "operating_rate_s3_dps": ("release", lambda r: r["operating_section_rate_dps"][2]),
    "operating_rate_ratio_s1": ("release", lambda r: r["operating_rate_over_ceiling"][0]),
    "operating_rate_ratio_s2": ("release", lambda r: r["operating_rate_over_ceiling"][1]),
    "operating_rate_ratio_s3": ("release", lambda r: r["operating_rate_over_ceiling"][2]),
    "delay_best_tau_s": ("delay_sweep", lambda r: r["speed_optimal_taus"]),
    "delay_attach_le_030": ("delay_sweep", lambda r: r["attach_le_030"]["fraction"]),
    "delay_attach_ge_045": ("delay_sweep", lambda r: r["attach_ge_045"]["fraction"]),
    "delay_n": ("delay_sweep", lambda r: r["n"]),
    "delay_supported_tau_s": ("delay_sweep", lambda r: r["supported_tau_s"]),
    "attach_near_fast_fraction": ("attachment", lambda r: r["near_fast_fraction"]),
    "attach_near_fast_n": ("attachment", lambda r: r["near_fast_n"]),
    "attachment_auc": ("attachment", lambda r: r["auc_grouped_cv"]),
    "ramped_fast_n": ("release", lambda r: r["ramped_fast_n"]),
    "ramped_slow_n": ("release", lambda r: r["ramped_slow_n"]),
    "delay_closest_attached_mm": ("delay_sweep", lambda r: 1e3 * r["closest_attached_median_m"]),
    "heldbase_base_within_100ms": ("heldbase", lambda r: r["fraction_within"]["base"]),
    "heldbase_clock_within_100ms": ("heldbase", lambda r: r["fraction_within"]["clock"]),
    "heldbase_residual_within_100ms": ("heldbase", lambda r: r["fraction_within"]["residual"]),
    "heldbase_neighbour_within_100ms": ("heldbase", lambda r: r["fraction_within"]["neighbour"]),
    "heldbase_residual_trigger_ticks": ("heldbase", lambda r: r["residual_trigger_ticks"]),
    "heldbase_residual_quiet_ticks": ("heldbase", lambda r: r["residual_quiet_ticks"]),
    "heldbase_n": ("heldbase", lambda r: r["n"]),
}


def _ours(fits, out) -> None:
    for cid, (fit, get) in OURS.items():
        out[cid] = get(fits[fit])


def rows(fits: dict, path=None) -> list[dict]:
    """fits: fit name -> (artifact path, its JSON)."""
    return claim_rows("characterize", _ours, fits, *([path] if path else []))
