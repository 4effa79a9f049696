"""Motion capture and servo log: what the rig's recorders would have written for a trial.

Mocap: 240 Hz from the physics steps (positions interpolated linearly, orientations by nlerp),
mapped into the lab by the session's calibration (base position and a small rotation), with
sub-millimetre noise and short dropouts (`*_valid` false, pose NaN).
Servo log: one sync-read about every 10 ms with jittered timestamps: goal (int), present (int) and
current (mA, from cable tension).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..quat import from_rotvec as quat_from_rotvec
from ..quat import mat_apply, norm3, qmul
from ..quat import to_matrix as quat_to_mat
from ..rawformat import BODIES, MOCAP_HZ, mocap_columns, servo_columns
from . import servo as SV

POS_NOISE_M = 0.0003  # 0.3 mm per axis
ANG_NOISE_RAD = np.deg2rad(0.15)
DROPOUT_RATE_HZ = 0.6  # dropout events per body per second
DROPOUT_LEN = (1, 8)  # samples (<= 33 ms: bridged by the 0.1 s gap rule downstream)


def _resample(t_step, x, t_out):
    """Linear interpolation of (T, ...) samples onto t_out along axis 0."""
    idx = np.clip(np.searchsorted(t_step, t_out) - 1, 0, len(t_step) - 2)
    a = ((t_out - t_step[idx]) / (t_step[idx + 1] - t_step[idx])).reshape((-1,) + (1,) * (x.ndim - 1))
    return x[idx] * (1 - a) + x[idx + 1] * a


def base_meta(sess: dict) -> dict:
    """meta.json's `base` (the session's mount pose in the lab) and `axis` (the base's -y, along
    which the arm hangs, unit). Elementwise, as the recordings are, so its last bits are the same
    on every CPU (a BLAS product's were not)."""
    a = mat_apply(quat_to_mat(np.asarray(sess["base_quat"], float)), [0.0, -1.0, 0.0])
    return dict(base=dict(pos=[float(x) for x in sess["base_pos"]], quat=[float(x) for x in sess["base_quat"]]),
                axis=[float(x) for x in a / norm3(a)])


def _to_lab(p, R, B):
    return mat_apply(R, p) + B


def mocap_frame(trial, calib: dict, target: dict | None, rng: np.random.Generator) -> pd.DataFrame:
    """trial: sim.Trial in the arm frame. calib: base_pos (lab), base_quat (lab from arm)."""
    t_step = trial.t
    n = int(np.floor((t_step[-1] - t_step[0]) * MOCAP_HZ))
    t = t_step[0] + np.arange(n) / MOCAP_HZ
    B = np.asarray(calib["base_pos"], float)
    qB = np.asarray(calib["base_quat"], float)
    R = quat_to_mat(qB)
    pos = _resample(t_step, trial.pos, t)  # (n, 3, 3)
    quat = _resample(t_step, trial.quat, t)
    quat /= np.linalg.norm(quat, axis=-1, keepdims=True)
    poses = {}
    poses["base"] = (_to_lab(_resample(t_step, trial.base, t), R, B), np.tile(qB, (n, 1)))  # the mount translates
    for j, b in enumerate(("s1", "s2", "tip")):
        poses[b] = (_to_lab(pos[:, j], R, B), qmul(qB[None], quat[:, j]))
    if target is not None and trial.target_pos is not None:  # a free block (deployment): it moves
        tq = _resample(t_step, trial.target_quat, t)
        tq /= np.linalg.norm(tq, axis=-1, keepdims=True)
        poses["target"] = (_to_lab(_resample(t_step, trial.target_pos, t), R, B), qmul(qB[None], tq))
    elif target is not None:
        poses["target"] = (
            np.tile(_to_lab(target["pos"], R, B), (n, 1)),
            np.tile(qmul(qB, target["quat"]), (n, 1)),
        )
    cols = {"t": t}
    for b in BODIES:
        if b not in poses:
            for f in ("x", "y", "z", "qw", "qx", "qy", "qz"):
                cols[f"{b}_{f}"] = np.full(n, np.nan)
            cols[f"{b}_valid"] = np.zeros(n, bool)
            continue
        p, q = poses[b]
        p = p + rng.normal(0, POS_NOISE_M, p.shape)
        q = qmul(q, quat_from_rotvec(rng.normal(0, ANG_NOISE_RAD, (n, 3))))
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        q *= np.where(q[:, :1] < 0, -1.0, 1.0)  # one hemisphere: w >= 0
        valid = np.ones(n, bool)
        for _ in range(rng.poisson(DROPOUT_RATE_HZ * n / MOCAP_HZ)):
            k = rng.integers(0, n)
            valid[k : k + rng.integers(DROPOUT_LEN[0], DROPOUT_LEN[1] + 1)] = False
        p[~valid] = np.nan
        q[~valid] = np.nan
        for i, f in enumerate("xyz"):
            cols[f"{b}_{f}"] = p[:, i]
        for i, f in enumerate(("qw", "qx", "qy", "qz")):
            cols[f"{b}_{f}"] = q[:, i]
        cols[f"{b}_valid"] = valid
    return pd.DataFrame(cols)[mocap_columns()]


def servo_frame(t_step, goals, present, tension, rng: np.random.Generator) -> pd.DataFrame:
    """present: the simulated present positions (sim.Trial.present, loaded loop)."""
    """~100 Hz sync-read log with jittered timestamps (USB latency)."""
    dts = np.clip(rng.normal(0.010, 0.0015, int((t_step[-1] - t_step[0]) / 0.006) + 2), 0.006, 0.016)
    t = t_step[0] + 0.002 + np.cumsum(dts)
    t = t[t < t_step[-1]]
    idx = np.searchsorted(t_step, t, side="right") - 1
    pres = _resample(t_step, present, t)
    ten = tension[idx]
    moving = np.abs(goals[idx] - pres) > 5
    cols = {"t": t}
    cur = SV.current_ma(ten, moving, rng)
    for i in range(9):
        cols[f"goal_{i + 1}"] = np.rint(goals[idx, i]).astype(np.int64)
        cols[f"present_{i + 1}"] = np.rint(pres[:, i]).astype(np.int64)
        cols[f"current_{i + 1}"] = np.round(cur[:, i], 1)
    return pd.DataFrame(cols)[servo_columns()]
