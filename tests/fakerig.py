"""A tiny writer of VALID groups in the rig format, for the data layer's unit tests only.

Kinematics of a hanging three-section arm in closed form (constant bend direction `phi`,
section angles that sway and, optionally, snap), so a test knows the exact base-frame state
the resampler must recover. 240 Hz mocap (`mocap_hz` for another rate) with a few short dropouts (NaN while invalid), a
jittered ~100 Hz servo log with step goals and a first-order present position. Seeded, so
every call writes the same bytes. Rotations use quaternion products, independent of the
matrix code in resample.py that the tests check.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from embodied_snap.rawformat import (
    MOCAP_HZ,
    N_SERVOS,
    SERVO_IDS,
    TIP_AXIS_LOCAL,
    mocap_columns,
    servo_columns,
    write_group,
    write_index,
)

# S1, S2, S3 + the 150 mm end effector (paper section II), metres.
LENGTHS = (0.324, 0.230, 0.176 + 0.150)
BASE_POS = (0.12, 1.65, -0.30)
# (body, start time after t0 [s], samples lost at 240 Hz): short dropouts, all bridged at
# max_gap_s=0.1; the target's is long on purpose (the target is not part of x_t). At another
# mocap rate a dropout loses the samples of about the same span in seconds.
DROPOUTS = (("tip", 1.0, 6), ("s2", 2.5, 12), ("base", 4.0, 3), ("target", 3.0, 60))


def qmul(a, b):
    aw, ax, ay, az = np.moveaxis(np.asarray(a, float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, float), -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def qaxis(axis, angle):
    axis = np.asarray(axis, float)
    angle = np.asarray(angle, float)[..., None]
    return np.concatenate([np.cos(angle / 2), np.sin(angle / 2) * axis], axis=-1)


def qrot(q, v):
    """Rotate vector(s) v by unit quaternion(s) q: q v q*."""
    q = np.asarray(q, float)
    v = np.broadcast_to(np.asarray(v, float), q.shape[:-1] + (3,))
    qv = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)
    return qmul(qmul(q, qv), q * np.array([1.0, -1.0, -1.0, -1.0]))[..., 1:]


# Base yawed 30 deg about Y and tilted 5 deg about X: a rotated, translated base frame.
BASE_QUAT = tuple(qmul(qaxis((0, 1, 0), np.radians(30)), qaxis((1, 0, 0), np.radians(5))))


def section_angles(t, snap_at=3.0, static=False):
    """Cumulative bend angles (n,3) of S1..S3: slow sway plus a fast recoil at `snap_at`."""
    t = np.asarray(t, float)
    if static:
        return np.tile([0.2, 0.45, 0.8], (len(t), 1))
    sway = 0.15 * np.sin(2 * np.pi * 0.4 * t)[:, None] * np.array([1.0, 1.5, 2.0])
    pre = np.array([0.25, 0.55, 0.9])
    snap = 0.0 if snap_at is None else 0.5 * (1 - np.tanh((t - snap_at) / 0.08))[:, None] / 2
    # Before the snap the preloaded sections are bent by `pre`; the recoil releases them.
    return sway + pre * (0.3 + snap)


def arm_in_base(t, phi=0.7, snap_at=3.0, static=False):
    """Base-frame positions of s1, s2, tip (n,3 each) and body quaternions (n,4 each)."""
    th = section_angles(t, snap_at, static)
    bend_axis = np.array([-np.sin(phi), 0.0, np.cos(phi)])  # turns -Y towards azimuth phi
    out, p = {}, np.zeros((len(th), 3))
    for k, body in enumerate(("s1", "s2", "tip")):
        q = qaxis(bend_axis, th[:, k])
        p = p + LENGTHS[k] * qrot(q, TIP_AXIS_LOCAL)
        out[body] = (p.copy(), q)
    return out


def expected_state(t, phi=0.7, snap_at=3.0, static=False):
    """The 12 geometric entries of x_t (s1, s2, tip positions and the tip axis, base frame)."""
    arm = arm_in_base(t, phi, snap_at, static)
    axis = qrot(arm["tip"][1], TIP_AXIS_LOCAL)
    return np.concatenate([arm["s1"][0], arm["s2"][0], arm["tip"][0], axis], axis=1)


def make_mocap(
    t, base_pos=BASE_POS, base_quat=BASE_QUAT, dropouts=DROPOUTS, phi=0.7, snap_at=3.0, static=False,
    hz=MOCAP_HZ,
):
    n = len(t)
    bq = np.tile(np.asarray(base_quat, float), (n, 1))
    bp = np.tile(np.asarray(base_pos, float), (n, 1))
    poses = {"base": (bp, bq)}
    for body, (p, q) in arm_in_base(t - t[0], phi, snap_at, static).items():
        poses[body] = (bp + qrot(bq, p), qmul(bq, q))
    poses["target"] = (np.tile([0.45, 1.05, 0.10], (n, 1)), np.tile([1.0, 0, 0, 0], (n, 1)))
    cols = {"t": t}
    for body, (p, q) in poses.items():
        valid = np.ones(n, bool)
        for b, start, k in dropouts:
            if b == body:
                i = int(round(start * hz))
                valid[i : i + int(round(k * hz / MOCAP_HZ))] = False
        p, q = p.copy(), q.copy()
        p[~valid], q[~valid] = np.nan, np.nan  # the exporter writes NaN where tracking was lost
        for j, f in enumerate("xyz"):
            cols[f"{body}_{f}"] = p[:, j]
        for j, f in enumerate(("qw", "qx", "qy", "qz")):
            cols[f"{body}_{f}"] = q[:, j]
        cols[f"{body}_valid"] = valid
    return pd.DataFrame(cols)[mocap_columns()]


def goal_program(t, n_servos=N_SERVOS):
    """Step goals (ticks): preload at 0.5 s, release at 2.9 s, hold again at 4.5 s."""
    t = np.asarray(t, float)
    base = 2048 + 100 * np.arange(n_servos)
    load = np.where((t >= 0.5) & (t < 2.9), 600, 0) + np.where(t >= 4.5, 250, 0)
    return (base[None, :] + load[:, None] * (1 + np.arange(n_servos) % 3)[None, :]).astype(np.int64)


def make_servo(t0, t1, seed=0, tau=0.03):
    rng = np.random.default_rng(seed)
    n = int(np.ceil((t1 - t0) * 100)) + 1
    t = t0 + np.arange(n) * 0.01 + rng.uniform(-0.002, 0.002, n)  # sync-read jitter
    goal = goal_program(t - t0)
    # First-order response to the step goal, evaluated exactly on the log's own times.
    present = np.empty_like(goal, dtype=float)
    present[0] = goal[0]
    for k in range(1, n):
        a = np.exp(-(t[k] - t[k - 1]) / tau)
        present[k] = goal[k - 1] + (present[k - 1] - goal[k - 1]) * a
    cols = {"t": t}
    for j, i in enumerate(SERVO_IDS):
        cols[f"goal_{i}"] = goal[:, j]
        cols[f"present_{i}"] = np.round(present[:, j]).astype(np.int64)
        cols[f"current_{i}"] = np.clip(40.0 + 1.5 * np.abs(goal[:, j] - present[:, j]), 0, 1200)
    return pd.DataFrame(cols)[servo_columns()]


def write_fake_group(
    raw_dir,
    group_id="dyn_0001",
    evidence_set="dynamics",
    category="free_space",
    session="s01",
    duration_s=6.0,
    seed=0,
    t0=12.5,
    mocap_hz=MOCAP_HZ,
    **kinematics,
) -> dict:
    """Write one valid group (mocap at mocap_hz); return its index.csv row."""
    t = t0 + np.arange(int(round(duration_s * mocap_hz)) + 1) / mocap_hz
    mocap = make_mocap(t, hz=mocap_hz, **kinematics)
    # The target is placed by hand, a millimetre apart per seed: without noise, two groups would
    # otherwise hold the same mocap bytes, one recording the gate refuses in two groups.
    mocap["target_x"] += 0.001 * seed
    # The servo log starts a little before and ends a little after the mocap.
    servo = make_servo(t[0] - 0.03, t[-1] + 0.03, seed=seed)
    base_pos = kinematics.get("base_pos", BASE_POS)
    base_quat = kinematics.get("base_quat", BASE_QUAT)
    meta = {
        "group_id": group_id,
        "evidence_set": evidence_set,
        "category": category,
        "session": session,
        "base": {"position": [float(v) for v in base_pos], "quaternion": [float(v) for v in base_quat]},
        "axis": [float(v) for v in qrot(np.asarray(base_quat, float), TIP_AXIS_LOCAL)],
        "program": {
            "kind": "primitive",
            "rho1": 0.6,
            "rho2": 0.5,
            "rho3": 0.3,
            "s3": 0.2,
            "dphi": 0.0,
            "tau": 0.55,
            "bearing": 0.7,
        },
        # Times inside the recording (goal_program: preload at 0.5 s, release at 2.9 s).
        "labels": {"attached": False, "retrieved": False, "snap_speed_event": True,
                   **{k: round(float(t[0]) + dt, 4) for k, dt in (("t_preload", 0.5), ("t_slack", 2.8),
                                                                   ("t_s2", 2.85), ("t_s1", 2.9))}},
    }
    write_group(raw_dir, meta, mocap, servo)
    return {
        "group_id": group_id,
        "evidence_set": evidence_set,
        "category": category,
        "session": session,
        "recorded_at": f"2026-03-{1 + seed % 28:02d}T10:{seed % 60:02d}:00Z",
        "n_mocap": len(mocap),
        "n_servo": len(servo),
    }


def write_fake_raw(raw_dir, group_ids=("dyn_0001", "dyn_0002"), duration_s=6.0, **kw) -> list[dict]:
    """Write several valid groups and their index.csv."""
    rows = [
        write_fake_group(raw_dir, g, seed=i, duration_s=duration_s, **kw) for i, g in enumerate(group_ids)
    ]
    write_index(rows, Path(raw_dir) / "index.csv")
    return rows
