"""The simulated rig's true parameters: a function of (seed, session) only.

The pipeline never reads this (rule: only the twin validation report compares fits against it).
"""

from __future__ import annotations

import numpy as np

from ..acquisition import programs as P
from ..acquisition.draws import rng_for
from ..quat import from_rotvec as quat_from_rotvec
from ..quat import qmul
from . import model as M
from . import servo as SV
from . import sim

# Fold latch and cup seal (identified against paper III; see docs/twin.md).
# catch_rate_rad_s: the curl must open at least this fast to hook (slow ramps slide off: no latch)
LATCH = dict(
    engage_rad=1.4, catch_rad=0.05, catch_rate_rad_s=0.5, creep_s=1.32,
    open_m=0.0074, break_nm=30.0, curl_min=4.99, curl_max=5.445,
)
# The seal's own physics, not a protocol value: the pipeline's attachment threshold (config
# characterize.attach_speed_mps, a tip speed) is measured against it. speed_mps is the cup's speed
# into the face that compresses it, identified from paper III-B's delay sweep (0/6 at tau <= 0.30 s,
# 27/27 at >= 0.45 s): the short delays reach the face at 0.8-1.1 m/s, the others at >= 1.8 m/s
# (docs/twin.md, "Cup seal").
SEAL = dict(gap_m=0.03, overlap_m=0.02, speed_mps=1.2, tilt_deg=120.0)
# The deployment's block (simulated hardware, chosen, not fitted): 50 g on a stand it leaves when the seal
# pulls it with more than its weight (0.49 N); the 20 mm Ecoflex cup lets go above hold_n.
BLOCK = dict(mass_kg=0.05, release_n=0.05 * 9.81, hold_n=3.0)
BASE_LAB = (0.0, 1.45, 0.0)  # m: the arm's mount in the lab, Y up


def session_index(session: str) -> int:
    return int(str(session).lstrip("s"))


def servo_params(seed: int) -> dict:
    r = rng_for(seed, "servos")
    return dict(
        rate=np.round(SV.RATE_RATED * r.uniform(0.95, 0.985, 9), 1).tolist(),
        tau=np.round(SV.TAU_NOMINAL * r.uniform(0.9, 1.1, 9), 4).tolist(),
    )


def session_params(seed: int, session: str) -> dict:
    """Arm parameters and mocap calibration of one acquisition session."""
    r = rng_for(seed, "session", session_index(session))
    p = dict(M.NOMINAL)
    scale = float(r.normal(1.0, 0.04))  # TPU stiffness drifts with temperature and wear
    p["sec_stiffness"] = tuple(round(k * scale, 6) for k in p["sec_stiffness"])
    p["ee_stiffness"] = round(p["ee_stiffness"] * scale, 6)
    p["frictionloss"] = round(p["frictionloss"] * float(r.uniform(0.8, 1.2)), 6)
    base = np.asarray(BASE_LAB) + r.normal(0, 0.003, 3)  # the mount is re-measured each session
    tilt = r.normal(0, np.deg2rad(0.6), 3)  # calibration wand: small frame rotation
    tilt[1] = r.uniform(-np.pi, np.pi) * 0.02  # and a little yaw (rig noise, not a protocol value)

    q = quat_from_rotvec(tilt)
    return dict(
        arm={k: (list(v) if isinstance(v, tuple) else v) for k, v in p.items()},
        stiffness_scale=round(scale, 5),
        base_pos=np.round(base, 6).tolist(),
        base_quat=(q / np.linalg.norm(q)).tolist(),
    )


def arm_params(sess: dict) -> dict:
    return {k: (tuple(v) if isinstance(v, list) else v) for k, v in sess["arm"].items()}


def truth(seed: int, n_sessions: int) -> dict:
    """The rig's true parameters: lever ratios d_p/k, servo rates and time constants, per-session
    stiffness and calibration, latch and seal parameters."""
    sessions = {f"s{i:02d}": session_params(seed, f"s{i:02d}") for i in range(1, n_sessions + 1)}
    return dict(
        seed=int(seed),
        tick_m=M.K_TICK,
        lever_ticks_per_rad=list(M.NOMINAL["lever_ticks_per_rad"]),  # geometric lever d_p/k
        # what a fit of Eq. 1 on held calibration bursts sees: the cables stretch under the
        # arm's weight, so the taut envelope is steeper than the geometric lever
        effective_lever_ticks_per_rad=effective_levers(),
        rate_ceiling_rad_s=[SV.RATE_RATED / x for x in M.NOMINAL["lever_ticks_per_rad"]],
        servo=servo_params(seed),
        rated_rate_tick_s=SV.RATE_RATED,
        latch=dict(LATCH),
        seal=dict(SEAL),
        sessions=sessions,
        segments_per_section=M.N_SEG,
    )


def effective_levers(amplitude: float = 2000.0, dt: float = 0.001) -> list[float]:
    """The slope of Eq. 1 a fit sees on this model: held bursts of each section (cable 1 pulling,
    bearing 0) under gravity, where the compliant cable is stretched by the load. Solved
    section by section from the true section bends (distal cables traverse the proximal ones)."""

    L = []
    p = dict(M.NOMINAL)
    for s in (1, 2, 3):
        goals, times = P.burst(s, 0.0, amplitude, dt)
        goals = goals[: int((times["t_down"] - 0.01) / dt)]
        pres = SV.present_from_goal(goals, dt, np.full(9, SV.RATE_RATED * 0.97), np.full(9, SV.TAU_NOMINAL))
        tr = sim.run(p, pres, dt, LATCH)
        # section bends from the body orientations (relative rotation angle), as mocap sees them
        c = np.array([1.0, -1, -1, -1])
        q = [np.array([1.0, 0, 0, 0])] + [tr.quat[-1, j] for j in range(3)]
        th = [2 * np.arccos(min(1.0, abs(qmul(q[j] * c, q[j + 1])[0]))) for j in range(3)]
        w = tr.present[-1, 3 * (s - 1)]
        L.append(float((w - sum(L[j] * th[j] for j in range(s - 1))) / th[s - 1]))
    return [round(x, 1) for x in L]
