"""Per-trial features of a release recording: what every release, attachment, snap and delay fit
reads. Only recordings and their program/labels, nothing from the simulator."""

from __future__ import annotations

import numpy as np

from ..cup import cup_from_axis, tip_axis
from . import load
from . import mocap as M


def features(mc, meta, end_effector_m: float, max_gap_s: float) -> dict:
    """Peak speed and section rates from the release on; with a target, the cup face's (tracked
    tip pose + end_effector_m along the tip axis, embodied_snap.cup, as in the policy reward)
    closest approach, lateral offset and tilt there. Mocap dropouts up to max_gap_s are bridged;
    the kinematics are on the 240 Hz grid whatever the take's rate (mocap.on_grid)."""
    mc = M.on_grid(mc)
    t = mc.t.to_numpy()
    t0 = load.release_start(meta)
    v_peak, t_peak = M.peak(M.tip_speed(mc, max_gap_s), t, t0)
    rates = M.section_rates(mc, max_gap_s)
    out = dict(v_peak=v_peak, t_peak=t_peak, t_release=t0,
               rate_peak=[M.peak(rates[:, s], t, t0)[0] for s in range(3)],
               closest_m=np.nan, lateral_m=np.nan, tilt_deg=np.nan)
    if "target" not in meta or not mc.target_valid.any():
        return out
    # Approach of the cup face: the compliant end effector beyond the tracked tip is not tracked,
    # its cups sit end_effector_m along the tip axis (the tip frame's -Y).
    axis = tip_axis(M.track(mc, "tip", ("qw", "qx", "qy", "qz"), max_gap_s=max_gap_s))
    cup = cup_from_axis(M.track(mc, "tip", max_gap_s=max_gap_s), axis, end_effector_m)
    tgt = M.track(mc, "target", max_gap_s=max_gap_s)
    d = np.linalg.norm(cup - tgt, axis=1)
    d[t < t0] = np.nan  # the approach after the release began (the block may be carried after)
    if np.all(np.isnan(d)):
        return out
    k = int(np.nanargmin(d))
    # Face normal of the struck face in the block's frame ("+z" -> local +Z), into the lab.
    face = meta["target"].get("face", "+z")
    n_loc = np.zeros(3)
    n_loc["xyz".index(face[1])] = 1.0 if face[0] == "+" else -1.0
    n = M.qrotate(M.track(mc, "target", ("qw", "qx", "qy", "qz"), max_gap_s=max_gap_s)[k], n_loc)
    # Tilt: angle between the cup axis and the direction into the face (0 = square on).
    tilt = np.degrees(np.arccos(np.clip(axis[k] @ -n, -1.0, 1.0)))
    out.update(closest_m=float(d[k]), lateral_m=float(np.hypot(*(cup[k] - tgt[k])[[0, 2]])), tilt_deg=float(tilt))
    return out


def table(raw_dir, groups, end_effector_m: float, max_gap_s: float) -> list[dict]:
    """Features of each group (cup face end_effector_m beyond the tip, config rig.end_effector_m),
    with its program and outcome labels."""
    rows = []
    for g in groups:
        mc, _, meta = load.group(raw_dir, g["group_id"])
        lab, prog = meta.get("labels", {}), meta.get("program", {})
        rows.append(dict(g, **features(mc, meta, end_effector_m, max_gap_s), attached=lab.get("attached"),
                         snap_speed_event=lab.get("snap_speed_event"),
                         **{k: prog.get(k) for k in ("kind", "rho1", "rho2", "rho3", "tau", "ramp_s")}))
    return rows
