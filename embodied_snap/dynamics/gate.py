"""Delay-sweep gate (paper IV-A, Fig. 4b,c): measured vs predicted peak tip speed and tip travel.

The sweep is excluded from every fit. Each trial is rolled out open loop (Eq. 4) for H = 25 steps
(0.5 s) from its recorded 20-step history ending at the last frame before the S1 release, with its
recorded commands; the delay tau enters only through that pre-release history and the commands.
Measured and predicted quantities use the same 50 Hz definition over the same 0.5 s:
peak speed = max_k |tip_{k+1} - tip_k| / dt, travel = the tip's path length.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from ..resample import COMMAND_COLUMNS, STATE_COLUMNS
from .hold import release_row
from .model import HISTORY, HORIZON, LOOKAHEAD, TIP

DT = 0.02


def speed_travel(tip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """tip (..., H+1, 3) from the anchor on -> peak speed (m/s), path length (m)."""
    step = np.linalg.norm(np.diff(tip, axis=-2), axis=-1)
    return step.max(-1) / DT, step.sum(-1)


def trials(frames: pd.DataFrame, metas: dict[str, dict]):
    """Rollout inputs of every sweep trial whose record covers history and horizon."""
    rows, xs, us, tips = [], [], [], []
    for gid, f in frames.groupby("group_id", sort=True):
        m = metas[gid]
        t = f["t"].to_numpy()
        i = release_row(t, m["labels"]["t_s1"])
        if i < HISTORY or i + HORIZON + LOOKAHEAD - 1 >= len(t):
            continue
        X = f[STATE_COLUMNS].to_numpy(np.float32)
        U = f[COMMAND_COLUMNS].to_numpy(np.float32)
        xs.append(X[i - HISTORY:i + 1])
        us.append(U[i - HISTORY + 1:i + HORIZON + LOOKAHEAD])
        tips.append(X[i:i + HORIZON + 1, TIP])
        rows.append(dict(group_id=gid, session=m["session"], tau=float(m["program"]["tau"])))
    return rows, np.asarray(xs), np.asarray(us), np.asarray(tips, np.float64)


@torch.inference_mode()
def sweep(models: dict, frames: pd.DataFrame, metas: dict[str, dict]) -> dict:
    """Per trial: measured and per-seed predicted peak speed and travel; per tau: medians."""
    rows, xs, us, tip = trials(frames, metas)
    v_meas, d_meas = speed_travel(tip)
    pred = {}
    for seed, model in models.items():
        x = model.rollout(torch.from_numpy(xs), torch.from_numpy(us), HORIZON).numpy()
        ptip = np.concatenate([tip[:, :1], x[..., TIP].astype(np.float64)], 1)
        pred[seed] = speed_travel(ptip)
    for k, r in enumerate(rows):
        r.update(v_meas=float(v_meas[k]), travel_meas_m=float(d_meas[k]),
                 v_pred={s: float(p[0][k]) for s, p in pred.items()},
                 travel_pred_m={s: float(p[1][k]) for s, p in pred.items()})
    tau = np.array([r["tau"] for r in rows])
    per_tau = []
    for t in np.unique(np.round(tau, 4)):
        m = np.isclose(tau, t)
        per_tau.append(dict(
            tau=float(t), n=int(m.sum()),
            v_meas=float(np.median(v_meas[m])), travel_meas_m=float(np.median(d_meas[m])),
            v_pred={s: float(np.median(p[0][m])) for s, p in pred.items()},
            travel_pred_m={s: float(np.median(p[1][m])) for s, p in pred.items()}))
    taus = np.array([p["tau"] for p in per_tau])
    best = {"measured": float(taus[np.argmax([p["v_meas"] for p in per_tau])])}
    best.update({s: float(taus[np.argmax([p["v_pred"][s] for p in per_tau])]) for s in pred})
    return {
        "n": len(rows),
        "trials": rows,
        "per_tau": per_tau,
        "best_tau_s": best,
        # Seed summaries over all trials: peak-speed ratio and travel difference to the measurement.
        "peak_speed_ratio": {s: float(np.median(p[0]) / np.median(v_meas)) for s, p in pred.items()},
        "travel_diff_pct": {s: float(100 * (np.median(p[1]) / np.median(d_meas) - 1)) for s, p in pred.items()},
        "max_speed_meas": float(v_meas.max()),
        "max_speed_pred": {s: float(p[0].max()) for s, p in pred.items()},
    }
