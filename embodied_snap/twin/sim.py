"""One trial on the arm: servo goals in, body trajectories and observed events out.

The present positions are precomputed from the goals (servo.py); the physics is stepped in a
plain Python loop because two things depend on the state: the fold latch and the cup seal.

Fold latch (paper III-B: "the folded lattice retains a curled tip as a mechanical latch"): once
S3 has been curled past `engage_rad` and its curl starts to open by `catch_rad` (its cables were
slackened), the curled tip catches on the arm and the closed fold holds the whole arm's shape. It
is one equality constraint per joint, switched on (a stable latch; an explicit stiff spring is
not). While latched, the servos keep paying out and the cables go slack behind the held shape, so
the stored elastic energy is no longer metered by the servo rate. The fold creeps (its held angles
in S2, S3 relax toward straight with time constant `creep_s`: stress relaxation of the TPU). It
is clamped shut by the S1 cables and pops when the most wound S1 cable hangs `open_m` slack (or,
as a fuse, when it carries more than `break_nm`). After the pop each section recoils freely until
a cable that still has take-up catches it.

Cup seal: a cup that reaches the target face with lateral overlap, a gap within `seal_gap_m`,
normal speed above `speed_mps` and tilt below `tilt_deg` seals (a ball joint to the block);
anything else bounces off the block (MuJoCo contact).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import model as M
from . import servo as SV

CUP_R = 0.02  # m, cup collision radius (simulated hardware, not a protocol value)
CHECK_S = 0.004  # s between latch / seal checks (independent of dt)
RATE_CHECKS = 5  # the curl's opening rate at the catch is measured over this many checks (20 ms)


@dataclass
class Trial:
    t: np.ndarray  # (T,) s, every physics step
    pos: np.ndarray  # (T, 3, 3) positions of s1, s2, tip (S3 distal end)
    quat: np.ndarray  # (T, 3, 4) orientations of those bodies (w, x, y, z)
    cup: np.ndarray  # (T, 3) cup face (end-effector tip) position
    tension: np.ndarray  # (T, 9) cable tensions, N (>= 0)
    present: np.ndarray  # (T, 9) servo present positions, ticks (unloaded loop minus deflection)
    base: np.ndarray  # (T, 3) mount position (arm frame; 0 at rest)
    events: dict = field(default_factory=dict)


def _ids(m):
    import mujoco

    segs = M.seg_names()
    last = {s: max(i for ss, i, _ in segs if ss == s) for s in (1, 2, 3)}
    bodies = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"seg{s}_{last[s]}") for s in (1, 2, 3)]
    sites = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, n) for n in M.BODY_NAMES]
    cup = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "cup")
    mount = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "mount")
    # dof addresses per section
    dofs = {s: [] for s in (1, 2, 3, 4)}
    for s, _i, name in segs:
        for ax in "zx":
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_{ax}")
            dofs[s].append(int(m.jnt_dofadr[j]))
    return bodies, sites, cup, mount, {s: np.array(v) for s, v in dofs.items()}


def section_bend(q: np.ndarray, dofs: dict, s: int) -> float:
    """Bend magnitude of section s in rad (small-angle sum of its joints' bend vectors)."""
    qq = q[dofs[s]].reshape(-1, 2)
    return float(np.hypot(qq[:, 0].sum(), qq[:, 1].sum()))


def run(
    p: dict,
    shaft: np.ndarray,
    dt: float,
    latch: dict,
    target: dict | None = None,
    seal: dict | None = None,
    wrench: dict | None = None,
    rate: np.ndarray | None = None,
) -> Trial:
    """Step the arm with the servos' unloaded loop response `shaft` (T, 9 ticks, one row per
    physics step, servo.present_from_goal). Every step the present position is the shaft minus
    the loop's deflection under the cable tension of the step before (servo.deflection; the loop
    is 50x stiffer than the cable, so the explicit coupling is stable), and the cable's free
    length follows it. The gearbox is not backdrivable: the load moves the loop no faster than
    the motor runs, so the present position changes by at most `rate` (tick/s per servo, default
    the rated ceiling) per step. `wrench`: external forces (N, arm frame) {"mount": (T, 3), "proximal":
    (T, 3)}, applied (MuJoCo xfrc_applied) on the rows where they are non-zero."""
    import mujoco

    m = M.build(p, dt)
    d = mujoco.MjData(m)
    bodies, sites, cup_site, mount_site, dofs = _ids(m)
    n = shaft.shape[0]
    present = np.empty((n, 9))
    defl = np.zeros(9)
    step = (SV.RATE_RATED if rate is None else np.minimum(np.asarray(rate, float), SV.RATE_RATED)) * dt
    pushed = []
    if wrench is not None:
        for name, key in ((0, "mount"), (M.PROXIMAL, "proximal")):
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "base" if name == 0 else name)
            pushed.append((bid, np.asarray(wrench[key], float)))
        active = np.flatnonzero(np.any([np.any(f != 0, axis=1) for _, f in pushed], axis=0))
        span = (active[0], active[-1] + 1) if len(active) else (n, n)
    # every step, whole arrays are copied (no fancy indexing in the loop); selected afterwards
    site_buf = np.empty((n, m.nsite, 3))
    quat_buf = np.empty((n, m.nbody, 4))
    force = np.empty((n, 9))
    # the fold latch locks every arm joint (equalities in model.py order, S1 first); only the
    # distal fold (S2, S3) creeps
    eq_ids = np.arange(sum(len(dofs[s]) for s in (1, 2, 3)))
    creep_ids = eq_ids[len(dofs[1]) :]
    latch_dofs = np.concatenate([dofs[1], dofs[2], dofs[3]])
    eq_qadr = np.array([m.jnt_qposadr[m.eq_obj1id[e]] for e in eq_ids])
    every = max(1, int(round(CHECK_S / dt)))  # latch and seal are checked every CHECK_S
    ev = dict(latch_on=None, latch_off=None, latch_cause=None, sealed=None, contact=None)
    latched = False
    b3_hist = []
    relax = every * dt / latch["creep_s"]
    clamp = 0
    b3max = 0.0
    sealed = False
    if target is not None:
        tb = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "target")
        m.body_pos[tb] = target["pos"]
        m.body_quat[tb] = target["quat"]
        d.mocap_pos[0] = target["pos"]
        d.mocap_quat[0] = target["quat"]
        normal = np.asarray(target["normal"], float)  # face normal in block coordinates
        half = np.asarray(target["half"], float)
        R = np.asarray(target["R"], float)  # columns: block axes in the arm frame
        tpos = np.asarray(target["pos"], float)
        face = float(half @ np.abs(normal))
        seal_eq = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, "seal")
        ee_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"ee_{M.N_EE - 1}")
        ee_len = p["ee_len"] / M.N_EE
    mujoco.mj_forward(m, d)
    for i in range(n):
        present[i] = shaft[i] - defl
        if i:
            present[i] = np.clip(present[i], present[i - 1] - step, present[i - 1] + step)
        free_len = -M.K_TICK * present[i]  # cable free length relative to the straight arm
        d.ctrl[:] = free_len
        if pushed and span[0] <= i <= span[1]:
            for bid, f in pushed:
                d.xfrc_applied[bid, :3] = f[i] if i < span[1] else 0.0
        mujoco.mj_step(m, d)
        site_buf[i] = d.site_xpos
        quat_buf[i] = d.xquat
        force[i] = d.actuator_force
        defl = SV.deflection(-force[i])
        if i % every:
            continue
        # --- fold latch ---
        q = d.qpos
        if not latched and ev["latch_on"] is None:
            # the fold forms once S3 has been curled past engage_rad and then starts to open
            # by catch_rad: the folded lattice catches on itself as soon as the curl unloads
            b3 = section_bend(q, dofs, 3)
            if b3 > latch["engage_rad"]:
                b3max = max(b3max, b3)
            b3_hist.append(b3)
            if b3max > 0 and b3 < b3max - latch["catch_rad"] and ev.get("curl") is None:
                # how fast the curl opens as it catches (over the last RATE_CHECKS checks)
                k = min(RATE_CHECKS, len(b3_hist) - 1)
                ev["catch_rate"] = (b3_hist[-1 - k] - b3) / (k * every * dt) if k else 0.0
                ev["curl"] = sum(section_bend(q, dofs, s) for s in (1, 2, 3))
                if ev["catch_rate"] < latch["catch_rate_rad_s"]:
                    # opened slowly (a ramped slackening): the tip slides along the arm instead of
                    # swinging into it and hooking, so there is no latch and the servos drag the release
                    ev["curl"] = 0.0
                # the curled tip can only hook onto the arm when the whole curl (sum of the
                # section bends) reaches curl_min; beyond curl_max it hooks so deep that the
                # S1 cables no longer clamp the fold and slackening them cannot open it (jam)
            if ev.get("curl") is not None and ev["curl"] >= latch["curl_min"]:
                latched = True
                m.eq_data[eq_ids, 0] = q[eq_qadr]
                d.eq_active[eq_ids] = 1
                clamp = int(np.argmax(shaft[i, :3]))  # the most wound S1 cable
                ev["latch_on"] = i * dt
        elif latched:
            m.eq_data[creep_ids, 0] -= m.eq_data[creep_ids, 0] * relax  # the TPU fold relaxes
            # the fold is clamped shut by the S1 cables: it pops once the most wound one hangs
            # open_m slack (servo paid out more than the held shape needs); a fuse at break_nm
            slack = free_len[clamp] - d.ten_length[clamp]
            load = np.abs(d.qfrc_constraint[latch_dofs]).sum()
            jammed = ev["curl"] > latch["curl_max"]
            if (slack > latch["open_m"] and not jammed) or load > latch["break_nm"]:
                latched = False
                d.eq_active[eq_ids] = 0
                ev["latch_off"] = i * dt
                ev["latch_cause"] = "slack" if slack > latch["open_m"] else "load"
        # --- cup seal on the target face ---
        if target is not None and not sealed and i >= 8:
            cup_i = site_buf[i, cup_site]
            rel = R.T @ (cup_i - tpos)  # cup in block coordinates
            gap = float(rel @ normal) - face - CUP_R  # < 0: the cup is compressed into the face
            lateral = np.abs(rel) * (1 - np.abs(normal))
            if -2 * face < gap < seal["gap_m"] and np.all(lateral <= half + seal["overlap_m"]):
                v = (cup_i - site_buf[i - 8, cup_site]) / (8 * dt)
                axis = -d.xmat[ee_body].reshape(3, 3)[:, 1]  # cup axis: local -Y of the cup body
                n_in = -(R @ normal)  # into the block
                tilt = float(np.degrees(np.arccos(np.clip(axis @ n_in, -1, 1))))
                if ev["contact"] is None:
                    ev.update(contact=i * dt, contact_speed=float(np.linalg.norm(v)), contact_tilt=tilt)
                if float(v @ n_in) >= seal["speed_mps"] and tilt <= seal["tilt_deg"]:
                    sealed = True
                    m.eq_data[seal_eq, 0:3] = [0.0, -ee_len, 0.0]
                    m.eq_data[seal_eq, 3:6] = R.T @ (cup_i - tpos)
                    d.eq_active[seal_eq] = 1
                    ev.update(sealed=i * dt, seal_speed=float(np.linalg.norm(v)), seal_tilt=tilt)
    pos, quat, cup = site_buf[:, sites], quat_buf[:, bodies], site_buf[:, cup_site]
    return Trial(np.arange(1, n + 1) * dt, pos, quat, cup, -force, present, site_buf[:, mount_site], ev)
