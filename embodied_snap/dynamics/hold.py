"""Quasi-static hold model (paper IV-A): the terminal pre-release configuration that starts a rollout.

A recorded hold is the 50 Hz state history up to the last frame before the S1 release (meta label
t_s1) of a training-split dynamics group, keyed by its program (rho1, rho2, rho3, s3). A new command
gets the inverse-distance average of the 12 nearest holds in that space, scaled by
(1500, 1500, 1500, 1000) ticks, with distances floored at 0.01; its support confidence is
C_h = 0.5 + 0.5 exp(-(d_mean / 0.3)^2) over the mean neighbour distance.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..resample import COMMAND_COLUMNS, STATE_COLUMNS
from .model import AXIS, HISTORY, TIP

KEYS = ("rho1", "rho2", "rho3", "s3")
SCALE = np.array([1500.0, 1500.0, 1500.0, 1000.0])
K, FLOOR, C_WIDTH = 12, 0.01, 0.3


def release_row(t: np.ndarray, t_s1: float) -> int:
    """Index of the last frame strictly before the S1 release."""
    return int(np.searchsorted(t, t_s1, side="left")) - 1


def bank(frames: pd.DataFrame, metas: dict[str, dict]) -> dict[str, np.ndarray]:
    """Holds of the given groups: q (n, 4) scaled keys, x (n, 21, 21) x_{t-20..t} before release,
    u (n, 20, 9) the commands of that history, session (n,), group_ids (n,)."""
    q, xs, us, sess, gids = [], [], [], [], []
    for gid, f in frames.groupby("group_id", sort=True):
        m = metas[gid]
        if "t_s1" not in m["labels"] or not all(k in m["program"] for k in KEYS):
            continue
        t = f["t"].to_numpy()
        i = release_row(t, m["labels"]["t_s1"])
        if i < HISTORY:
            continue
        X = f[STATE_COLUMNS].to_numpy(np.float32)
        U = f[COMMAND_COLUMNS].to_numpy(np.float32)
        q.append([m["program"][k] for k in KEYS])
        xs.append(X[i - HISTORY:i + 1])
        us.append(U[i - HISTORY + 1:i + 1])
        sess.append(m["session"])
        gids.append(gid)
    return {
        "q": np.asarray(q, np.float64).reshape(-1, 4) / SCALE,
        "x": np.asarray(xs, np.float32).reshape(-1, HISTORY + 1, len(STATE_COLUMNS)),
        "u": np.asarray(us, np.float32).reshape(-1, HISTORY, len(COMMAND_COLUMNS)),
        "session": np.asarray(sess, dtype=str),
        "group_ids": np.asarray(gids, dtype=str),
    }


def predict(bq: np.ndarray, bx: np.ndarray, q: np.ndarray, k: int = K):
    """Hold for commands q (m, 4) scaled: inverse-distance average of the k nearest bank entries.
    Returns x_hat (m, ...) like bx[0] and the support confidence C_h (m,)."""
    d = np.linalg.norm(q[:, None, :] - bq[None], axis=-1)  # (m, n)
    k = min(k, bq.shape[0])
    nn = np.argsort(d, axis=1, kind="stable")[:, :k]
    dn = np.take_along_axis(d, nn, 1)
    w = 1.0 / np.maximum(dn, FLOOR)
    w /= w.sum(1, keepdims=True)
    x = np.einsum("mk,mk...->m...", w, bx[nn])
    c = 0.5 + 0.5 * np.exp(-((dn.mean(1) / C_WIDTH) ** 2))
    return x, c


def axis_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1.0, 1.0)))


def leave_one_session_out(B: dict) -> dict:
    """Each hold predicted from the holds of the other sessions: tip (mm) and axis (deg) errors
    of the terminal frame."""
    tip, ax, ch = np.full(len(B["q"]), np.nan), np.full(len(B["q"]), np.nan), np.full(len(B["q"]), np.nan)
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
        "n_holds": int(len(tip)),
        "n_sessions": int(len(np.unique(B["session"]))),
        "tip_mm_median": float(np.median(tip[ok])),
        "tip_mm_mean": float(np.mean(tip[ok])),
        "axis_deg_median": float(np.median(ax[ok])),
        "axis_deg_mean": float(np.mean(ax[ok])),
        "tip_pct_arm_median": float(np.median(tip[ok]) / 730.0 * 100),
        "c_h_median": float(np.median(ch[ok])),
    }
