"""What each evidence set commands: nine servo-goal traces (ticks, seconds) and their phase times.

The same traces drive the simulated rig and the lab's arm (`esnap lab acquire`). The goal map itself
(the Eq. 1 preload map and the instantaneous release) is the primitive's, shared with the pipeline:
embodied_snap.primitive. The protocol numbers config carries (the canonical bearing, the S2 ramp,
the policy ranges, the rated servo speed the ramps are planned under) come in as a `Protocol`
(embodied_snap.protocol); what stays here is the acquisition's own choice of programs.
"""

from __future__ import annotations

import numpy as np

from ..primitive import cable_gains as _g
from ..primitive import release_goals, section_goals
from ..protocol import Protocol, window_span

PLAN_MARGIN = 0.9  # preload ramps are planned at this fraction of the rated speed: under the ceiling
# The acquisition's operating point: where release-mode, sweep and held-base trials sit
# (the pipeline finds its own operating point from P_snap; config has none).
OPERATING = dict(rho1=3100.0, rho2=2750.0, rho3=2900.0, s3=30.0, dphi=0.0, tau=0.55)
SWEEP_LOW = (0.15, 0.30)  # delay-sweep delays; none in (0.30, 0.45), as in the paper
SWEEP_HIGH = (0.45, 0.50, 0.55, 0.60, 0.65, 0.70, 0.75)
T_HANG = 0.25  # s of free hanging before anything moves
T_SETTLE = 0.5  # s held at full preload
T_S2 = 1.0  # s from S3 slack to the start of the S2 release: the latched tip settles
T_AFTER = 1.1  # s recorded after the S1 release


def dynamics_record_s(proto: Protocol) -> float:
    """How long a dynamics group is recorded: long enough for config windows.per_dynamics_group
    windows, as the paper's groups are (IV-A: 11,284 sealed windows from 20 groups). A group of n
    grid frames gives n - before - after windows (protocol.window_span)."""
    w = proto.windows
    before, after = window_span(w.history, w.lookahead, w.horizon)
    return (w.per_dynamics_group + before + after) / proto.sampling.hz


def sweep_tau(n: int) -> float:
    """Delay of the n-th (1-based) sweep trial: 2 of every 11 trials at a short delay, so the
    paper's 33 trials give 6 at <= 0.30 s and 27 at >= 0.45 s."""
    i = n - 1
    if i % 11 < 2:
        return SWEEP_LOW[i % 11]
    k = (i // 11) * 9 + i % 11 - 2  # index among the long-delay trials
    return SWEEP_HIGH[k % len(SWEEP_HIGH)]


def _preload(rho, bearing, dt, rated_tick_s):
    """Rest, then a linear ramp to the preload that every servo can follow (per-section scaling:
    all nine goals reach their targets together, so no cable runs ahead of its neighbours)."""
    W = section_goals(rho, bearing)
    dur = max(np.abs(W).max() / (PLAN_MARGIN * rated_tick_s), 0.2)
    return W, dur


def primitive(p: dict, bearing: float, dt: float, proto: Protocol, ramp_s: float = 0.0):
    """The four-stage snap primitive (paper III-B): preload, S3 slack, S2 over the protocol's S2
    ramp, S1 after tau.

    ramp_s > 0 stretches the whole release over ramp_s seconds (the 'ramped' release mode, paper
    III-B: "ramping the same command over 1-6 s"): S3 slack and S2 release together, then, tau
    after that ramp ends, S1 paid out over ramp_s as well. Whether the fold latches (a fast snap)
    or not (the servos drag the arm open) is the rig's, not the program's.
    """
    rho = (p["rho1"], p["rho2"], p["rho3"])
    W, dur = _preload(rho, bearing, dt, proto.rig.rated_speed_tick_s)
    s2_ramp = proto.primitive.s2_ramp_s
    t_s = T_HANG + dur + T_SETTLE
    if ramp_s > 0:
        t2, s2_ramp = t_s, ramp_s
    else:
        t2 = t_s + T_S2
    t1 = t2 + s2_ramp + p["tau"] if ramp_s > 0 else t2 + p["tau"]
    # a dynamics group goes on recording the hanging arm to its length (draws.draw_program)
    t_end = max(t1 + ramp_s + T_AFTER, p.get("record_s", 0.0))
    t = np.arange(int(round(t_end / dt))) * dt
    goals = np.zeros((len(t), 9))
    ramp = (t >= T_HANG) & (t < T_HANG + dur)
    goals[ramp] = W[None, :] * ((t[ramp] - T_HANG) / dur)[:, None]
    goals[(t >= T_HANG + dur) & (t < t_s)] = W
    rel = t >= t_s
    tr = t[rel]
    if ramp_s > 0:
        a3 = a2 = np.clip(1.0 - (tr - t_s) / ramp_s, 0.0, 1.0)
        a1 = np.clip(1.0 - (tr - t1) / ramp_s, 0.0, 1.0)  # S1 paid out over ramp_s too
        c = _g(bearing)
        cum = np.stack([rho[0] * a1, rho[0] * a1 + rho[1] * a2, rho[0] * a1 + rho[1] * a2 + rho[2] * a3], 1)
        g = (cum[:, :, None] * c[None, None, :]).reshape(-1, 9)
        g[:, 6:9] -= (p["s3"] * (1.0 - a3))[:, None]
        # a released cable is never taken up again: running minimum from the full preload
        goals[rel] = np.minimum.accumulate(np.vstack([W[None, :], g]), axis=0)[1:]
    else:
        goals[rel] = release_goals(np.asarray(rho), p["s3"], bearing, tr, t2, t1, s2_ramp)
    times = dict(t_preload=T_HANG, t_slack=t_s, t_s2=t2, t_s1=t1)
    return goals, times


def direct_release(p: dict, bearing: float, dt: float, proto: Protocol, sync: bool = True):
    """Direct tendon-driven release: a preload, then the pull-side goals back to rest. With
    `sync` the nine goals ramp down together at the rated ceiling of the longest cable (the
    section-wise rate limit of the paper's protocol, so no cable runs ahead and goes spuriously
    slack); otherwise every goal steps to rest and each servo pays out at its own ceiling. The tip
    curl stays below the fold angle (no latch)."""
    rated = proto.rig.rated_speed_tick_s
    rho = (p["rho1"], p["rho2"], p["rho3"])
    W, dur = _preload(rho, bearing, dt, rated)
    t_r = T_HANG + dur + T_SETTLE
    T_rel = np.abs(W).max() / rated if sync else 0.0
    t_end = t_r + np.abs(W).max() / 3000.0 + 0.6
    t = np.arange(int(round(t_end / dt))) * dt
    goals = np.zeros((len(t), 9))
    ramp = (t >= T_HANG) & (t < T_HANG + dur)
    goals[ramp] = W[None, :] * ((t[ramp] - T_HANG) / dur)[:, None]
    goals[(t >= T_HANG + dur) & (t < t_r)] = W
    rel = t >= t_r
    a = np.clip(1.0 - (t[rel] - t_r) / T_rel, 0.0, 1.0) if sync else np.zeros(rel.sum())
    # pull side to rest; antagonists stay paid out
    goals[rel] = np.minimum(
        W[None, :] * a[:, None], np.minimum(W, 0.0)[None, :] + np.maximum(W, 0.0)[None, :] * a[:, None]
    )
    return goals, dict(t_preload=T_HANG, t_release=t_r)


def burst(section: int, bearing: float, amp: float, dt: float):
    """Servo-calibration burst: one section's three cables step to a take-up and back."""
    # only that section's own cables move (the others stay at rest)
    mask = np.zeros(9, bool)
    mask[3 * (section - 1) : 3 * section] = True
    W = np.where(mask, amp * np.tile(_g(bearing), 3), 0.0)
    t_up, hold = 0.3, 0.9
    t_dn = t_up + hold
    t_end = t_dn + 0.8
    t = np.arange(int(round(t_end / dt))) * dt
    goals = np.zeros((len(t), 9))
    goals[(t >= t_up) & (t < t_dn)] = W
    return goals, dict(t_up=t_up, t_down=t_dn)


def goals_of(prog: dict, dt: float, proto: Protocol):
    """The goal trace (T, 9) at step dt and the phase times of a drawn program (draws.draw_program)."""
    if prog["kind"] == "burst":
        return burst(prog["section"], prog["bearing"], prog["amplitude"], dt)
    if prog["kind"] == "direct":
        return direct_release(prog, prog["bearing"], dt, proto)
    return primitive(prog, prog["bearing"], dt, proto, ramp_s=prog.get("ramp_s", 0.0))
