"""Open-loop tip error over the horizon for persistence and the GRU (paper IV-A, Fig. 4a).

The model is trained on H = 25 steps (0.5 s at 50 Hz). The paper's 0.7 s point is reached by
continuing the same open-loop rollout (Eq. 4) to 0.7 s / dt = 35 steps with the recorded commands;
so that all horizons are measured on the same windows, only anchors whose group holds 35 recorded
future frames (and commands to t+39) are used, i.e. each group's last 10 anchors are dropped. The
step dt is the protocol's (protocol.GRID_HZ), passed in.
"""

from __future__ import annotations

import numpy as np
import torch

from ..sources import recordings
from .model import TIP
from .train import batch, prepare

REPORT_S = (0.3, 0.5, 0.7)  # s: where the paper reads the error (Fig. 4a, claims); on any grid step


def eval_horizon(dt: float) -> int:
    """Steps the evaluation rolls out: to the last report horizon (35 at 50 Hz)."""
    return round(max(REPORT_S) / dt)


def eligible(W: dict, horizon: int) -> np.ndarray:
    """Window indices whose group holds x_{t+horizon} and u_{t+horizon+lookahead-1}."""
    g = W["group"]
    end = np.r_[np.flatnonzero(g[1:] != g[:-1]), len(g) - 1]  # last row of each group
    last = end[np.searchsorted(end, W["anchors"])]
    return np.flatnonzero(W["anchors"] + horizon + int(W["lookahead"]) - 1 <= last)


def recordings_of(W: dict, idx: np.ndarray) -> dict:
    """The groups whose windows `idx` are evaluated, and those of the file with none eligible."""
    used = W["group_ids"][np.unique(W["group"][W["anchors"][idx]])]
    return recordings(W["group_ids"].tolist(), used.tolist(), "no window spans the evaluation horizon")


def persistence_tip_mm(W: dict, idx: np.ndarray, horizon: int) -> np.ndarray:
    """Per-window tip error (W, horizon) of x_hat_{t+h} = x_t."""
    a = W["anchors"][idx][:, None]
    tip = W["X"][:, TIP]
    return np.linalg.norm(tip[a + np.arange(1, horizon + 1)] - tip[a], axis=-1) * 1e3


@torch.inference_mode()
def model_tip_mm(model, W: dict, idx: np.ndarray, horizon: int, bs: int = 2048) -> np.ndarray:
    W = prepare(W) if "_start" not in W else W
    out = []
    for i in range(0, len(idx), bs):
        xs, us, y = batch(W, W["anchors"][idx[i:i + bs]], horizon)
        pred = model.rollout(xs, us, horizon)
        out.append((pred[..., TIP] - y[..., TIP]).norm(dim=-1).numpy() * 1e3)
    return np.concatenate(out) if out else np.zeros((0, horizon))


def summary(err: np.ndarray, dt: float, arm_length_m: float) -> dict:
    """Mean tip error per horizon step and at the paper's 0.3/0.5/0.7 s, in mm and % of the arm's
    length (the protocol's rig.arm_length_m)."""
    ARM_LENGTH_MM = arm_length_m * 1e3
    mean = err.mean(0)
    at = {f"{s:g}": float(mean[round(s / dt) - 1]) for s in REPORT_S}
    return {
        "n_windows": int(len(err)),
        "h": list(range(1, err.shape[1] + 1)),
        "tip_mm": [float(v) for v in mean],
        "tip_mm_median": [float(v) for v in np.median(err, 0)],
        "at_s_mm": at,
        "at_s_pct_arm": {k: 100 * v / ARM_LENGTH_MM for k, v in at.items()},
    }



@torch.inference_mode()
def carry_gap(model, W: dict, idx: np.ndarray, n: int = 512) -> dict:
    """Tip distance between the carried-state rollout and Eq. 4's literal re-encoding of the last
    20 frames at every step, over the windows' horizon, on the first n windows of idx (the
    re-encoding costs 11x more)."""
    W = prepare(W) if "_start" not in W else W
    horizon = int(W["horizon"])
    xs, us, y = batch(W, W["anchors"][idx[:n]], horizon)
    a = model.rollout(xs, us, horizon, carry=True)
    b = model.rollout(xs, us, horizon, carry=False)
    gap = (a[..., TIP] - b[..., TIP]).norm(dim=-1).numpy() * 1e3
    err = (b[..., TIP] - y[..., TIP]).norm(dim=-1).numpy() * 1e3
    return {"n_windows": int(len(gap)), "gap_mm_mean_h25": float(gap[:, -1].mean()),
            "gap_mm_max": float(gap.max()), "reencoded_err_mm_mean_h25": float(err[:, -1].mean())}
