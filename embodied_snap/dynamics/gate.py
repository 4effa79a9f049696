"""Delay-sweep gate (paper IV-A, Fig. 4b,c): measured vs predicted peak tip speed and tip travel.

The sweep is excluded from every fit. Each trial is rolled out open loop (Eq. 4) from its recorded
hold, the 20-step history ending at the last frame before the S2 release, under its recorded
commands, through the S2 release, the delay tau and the S1 release, until `after_s1` seconds after
the S1 release (the snap's peak comes 0.45-0.65 s after the S1 command on the rig, as the servos pay
the cable out). So tau acts through the commands, as it does in policy search. Measured and
predicted quantities use the same grid definition over the same window: peak speed =
max_k |tip_{k+1} - tip_k| / dt, travel = the tip's path length. The step dt and the window lengths
are the protocol's (embodied_snap.protocol), passed in.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from ..protocol import Protocol
from ..resample import COMMAND_COLUMNS, STATE_COLUMNS
from ..sources import recordings
from .hold import release_row
from .model import TIP


def speed_travel(tip: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """tip (..., H+1, 3) from the anchor on -> peak speed (m/s), path length (m)."""
    step = np.linalg.norm(np.diff(tip, axis=-2), axis=-1)
    return step.max(-1) / dt, step.sum(-1)


def trials(frames: pd.DataFrame, metas: dict[str, dict], after_s1: float, proto: Protocol) -> list[dict]:
    """Rollout inputs of every sweep trial whose record covers its history and window: x (21, 21),
    u (20 + H + 4, 9), the measured tip (H + 1, 3), H = its window in steps. proto: its sampling
    and windows sections."""
    dt, history, lookahead = proto.sampling.dt, proto.windows.history, proto.windows.lookahead
    out = []
    for gid, f in frames.groupby("group_id", sort=True):
        m = metas[gid]
        t = f["t"].to_numpy()
        i = release_row(t, m["labels"]["t_s2"])
        H = int(np.ceil((m["labels"]["t_s1"] + after_s1 - t[i]) / dt))
        if i < history or i + H + lookahead - 1 >= len(t):
            continue
        X = f[STATE_COLUMNS].to_numpy(np.float32)
        U = f[COMMAND_COLUMNS].to_numpy(np.float32)
        out.append(dict(group_id=gid, session=m["session"], tau=float(m["program"]["tau"]), H=H,
                        x=X[i - history:i + 1], u=U[i - history + 1:i + H + lookahead],
                        tip=X[i:i + H + 1, TIP].astype(np.float64)))
    return out


@torch.inference_mode()
def sweep(models: dict, frames: pd.DataFrame, metas: dict[str, dict], after_s1: float, proto: Protocol) -> dict:
    """Per trial: measured and per-seed predicted peak speed and travel; per tau: medians."""
    tr = trials(frames, metas, after_s1, proto)
    dt = proto.sampling.dt
    meas = np.array([speed_travel(r["tip"], dt) for r in tr])  # (n, 2)
    v_meas, d_meas = meas[:, 0], meas[:, 1]
    pred = {s: np.zeros((len(tr), 2)) for s in models}
    for H in sorted({r["H"] for r in tr}):  # one batch per window length
        k = [j for j, r in enumerate(tr) if r["H"] == H]
        xs = torch.from_numpy(np.stack([tr[j]["x"] for j in k]))
        us = torch.from_numpy(np.stack([tr[j]["u"] for j in k]))
        tip0 = np.stack([tr[j]["tip"][:1] for j in k])
        for seed, model in models.items():
            x = model.rollout(xs, us, H).numpy()
            pred[seed][k] = np.stack(speed_travel(np.concatenate([tip0, x[..., TIP].astype(np.float64)], 1), dt), 1)
    pred = {s: (p[:, 0], p[:, 1]) for s, p in pred.items()}
    rows = [{k: r[k] for k in ("group_id", "session", "tau", "H")} for r in tr]
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
        "recordings": recordings(list(metas), [r["group_id"] for r in rows],
                                 "its record does not cover the history and the window"),
        "window": {"from": "last frame before the S2 release", "after_s1_s": after_s1,
                   "rollout_steps": [min(r["H"] for r in rows), max(r["H"] for r in rows)]},
        "trials": rows,
        "per_tau": per_tau,
        "best_tau_s": best,
        # Seed summaries over all trials: peak-speed ratio and travel difference to the measurement.
        "peak_speed_ratio": {s: float(np.median(p[0]) / np.median(v_meas)) for s, p in pred.items()},
        "travel_diff_pct": {s: float(100 * (np.median(p[1]) / np.median(d_meas) - 1)) for s, p in pred.items()},
        "max_speed_meas": float(v_meas.max()),
        "max_speed_pred": {s: float(p[0].max()) for s, p in pred.items()},
    }
