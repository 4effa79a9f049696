"""Quasi-static hold model (paper IV-A): the pre-release configuration that starts a rollout.

A recorded hold is the state history x_{t-20..t} (the protocol's window history) up to the last
frame before the S2 release
(meta label t_s2) of a training-split dynamics group: the preload is set, S3 has been slackened and
the curled tip has settled, and nothing fast has happened yet. The rollout from there covers the S2
release, the delay tau and the S1 snap, so tau acts through the commands, as on the rig.

Each hold is keyed by its program (rho1, rho2, rho3, s3) and stored in the canonical bearing phi0
(the protocol's, config primitive.phi0_deg): positions and the tip axis are rotated about the
measured free-hanging axis n by phi0 - bearing, and servo positions are kept as their offsets from
the goals. A new command (rho, s3) aimed at phi0 + dphi gets the inverse-distance average of the 12
nearest holds in (rho1, rho2, rho3, s3),
scaled by (1500, 1500, 1500, 1000) ticks with distances floored at 0.01, rotated by dphi, with the
servo positions put back on its own goals. Support confidence C_h = 0.5 + 0.5 exp(-(d_mean/0.3)^2).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import bearing as BR
from ..resample import COMMAND_COLUMNS, STATE_COLUMNS
from .model import AXIS, TIP

KEYS = ("rho1", "rho2", "rho3", "s3")
SCALE = np.array([1500.0, 1500.0, 1500.0, 1000.0])
K, FLOOR, C_WIDTH = 12, 0.01, 0.3
VECTORS = (slice(0, 3), slice(3, 6), TIP, AXIS)  # s1, s2, tip, tip axis: rotate about n
SERVO = slice(12, 21)


def release_row(t: np.ndarray, t_label: float) -> int:
    """Index of the last frame strictly before a release label."""
    return int(np.searchsorted(t, t_label, side="left")) - 1


def hanging_axis(frames: pd.DataFrame) -> np.ndarray:
    """The measured free-hanging axis n: median direction of the tip at rest (each group's first
    frame, before anything moves), in the base frame."""
    tip = frames.groupby("group_id", sort=True)[STATE_COLUMNS[TIP]].first().to_numpy()
    n = np.median(tip / np.linalg.norm(tip, axis=1, keepdims=True), axis=0)
    return n / np.linalg.norm(n)


def rotate_states(x: np.ndarray, deg, n: np.ndarray) -> np.ndarray:
    """Rotate the position and axis parts of state histories x (T, 21) by a scalar deg, or
    x (m, T, 21) by deg (m,), about n; servo parts untouched."""
    x = np.array(x, copy=True)
    R = BR.rotation(deg, n).astype(x.dtype)
    if R.ndim == 3:
        R = R[:, None]  # one rotation per history, shared by its frames
    for s in VECTORS:
        x[..., s] = np.einsum("...ij,...j->...i", R, x[..., s])
    return x


def bank(frames: pd.DataFrame, metas: dict[str, dict], phi0_deg: float, history: int) -> dict[str, np.ndarray]:
    """Holds of the given groups in the canonical bearing phi0_deg: q (n, 4) scaled keys, x (n,
    history+1, 21) x_{t-20..t} before the S2 release (servo part: position - goal), n (3,) the
    hanging axis, session, group_ids."""
    n = hanging_axis(frames)
    q, xs, sess, gids = [], [], [], []
    for gid, f in frames.groupby("group_id", sort=True):
        m = metas[gid]
        if "t_s2" not in m["labels"] or not all(k in m["program"] for k in KEYS):
            continue
        t = f["t"].to_numpy()
        i = release_row(t, m["labels"]["t_s2"])
        if i < history:
            continue
        X = f[STATE_COLUMNS].to_numpy(np.float64)[i - history : i + 1]
        U = f[COMMAND_COLUMNS].to_numpy(np.float64)[i - history : i + 1]
        X = rotate_states(X, phi0_deg - float(m["program"]["bearing"]), n)
        X[:, SERVO] -= U
        q.append([m["program"][k] for k in KEYS])
        xs.append(X)
        sess.append(m["session"])
        gids.append(gid)
    return {
        "q": np.asarray(q, np.float64).reshape(-1, 4) / SCALE,
        "x": np.asarray(xs, np.float32).reshape(-1, history + 1, len(STATE_COLUMNS)),
        "n": n,
        "session": np.asarray(sess, dtype=str),
        "group_ids": np.asarray(gids, dtype=str),
    }


def predict(bq: np.ndarray, bx: np.ndarray, q: np.ndarray, k: int = K):
    """Hold for commands q (m, 4) scaled: inverse-distance average of the k nearest bank entries.
    Returns x_hat (m, ...) like bx[0] and the support confidence C_h (m,)."""
    d = np.linalg.norm(q[:, None, :] - bq[None], axis=-1)  # (m, n)
    k = min(k, bq.shape[0])
    nn = np.argpartition(d, k - 1, axis=1)[:, :k]  # the k nearest, in any order (weights are summed)
    dn = np.take_along_axis(d, nn, 1)
    w = 1.0 / np.maximum(dn, FLOOR)
    w /= w.sum(1, keepdims=True)
    x = np.einsum("mk,mk...->m...", w, bx[nn])
    c = 0.5 + 0.5 * np.exp(-((dn.mean(1) / C_WIDTH) ** 2))
    return x, c


def start(B: dict, params: dict, u_hist: np.ndarray):
    """Rollout start x_{t-20..t} (m, 21, 21) and C_h (m,) for commands params (arrays rho1, rho2,
    rho3, s3, dphi) whose goals over the 21 history frames are u_hist (m, 21, 9)."""
    q = np.stack([np.asarray(params[k], float) for k in KEYS], -1) / SCALE
    x, c = predict(B["q"], B["x"], q)
    x = rotate_states(x, np.asarray(params["dphi"], float), B["n"])
    x[..., SERVO] += u_hist
    return x.astype(np.float32), c


def axis_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1.0, 1.0)))


def leave_one_session_out(B: dict, arm_length_m: float) -> dict:
    """Each hold predicted from the holds of the other sessions (both canonical, i.e. compared at
    the hold's own bearing): tip (mm, and % of the arm's length) and axis (deg) errors of the
    terminal frame."""
    nh = len(B["q"])
    tip, ax, ch = np.full(nh, np.nan), np.full(nh, np.nan), np.full(nh, np.nan)
    for s in np.unique(B["session"]):
        out = B["session"] == s
        if out.all():
            continue
        x, c = predict(B["q"][~out], B["x"][~out, -1], B["q"][out])
        tip[out] = np.linalg.norm(x[:, TIP] - B["x"][out, -1, TIP], axis=-1) * 1e3
        ax[out] = axis_deg(x[:, AXIS], B["x"][out, -1, AXIS])
        ch[out] = c
    ok = np.isfinite(tip)
    return {
        "n_holds": int(nh),
        "n_sessions": int(len(np.unique(B["session"]))),
        "hanging_axis": [float(v) for v in B["n"]],
        "tip_mm_median": float(np.median(tip[ok])),
        "tip_mm_mean": float(np.mean(tip[ok])),
        "axis_deg_median": float(np.median(ax[ok])),
        "axis_deg_mean": float(np.mean(ax[ok])),
        "tip_pct_arm_median": float(np.median(tip[ok]) / (arm_length_m * 1e3) * 100),
        "c_h_median": float(np.median(ch[ok])),
    }
