"""Kinematics from the motion capture (any constant rate the gate passes): tip speed, section bend angle and bend rate.

The smoothing and differences are defined on the paper's 240 Hz capture (GRID_HZ): a take at
another rate is first interpolated onto that grid (on_grid), so a speed or bend rate means the
same seconds of motion whatever the lab's cameras ran at. At 120 Hz the kernels taken over the
take's own samples span twice the time and cut a release's peak bend rates by 25-40 %.

A section's bend is the rotation between its proximal and distal tracked frames (base->s1,
s1->s2, s2->tip). Every tracked frame is identity on the straight hanging arm, so a frame's
tangent is its local -Y axis.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.interpolate import CubicSpline

from ..quat import qconj, qmul, qrotate
from ..rawformat import POSE_FIELDS

SECTION_FRAMES = (("base", "s1"), ("s1", "s2"), ("s2", "tip"))
GRID_HZ = 240.0  # the rate smooth3 and the central differences are defined at (paper III)


def continuous(q: np.ndarray) -> np.ndarray:
    """Quaternions (n, 4) with each valid (non-NaN) row's sign chosen to follow the previous
    valid row's: q and -q are one rotation, and a capture system may flip between them, which
    would send any interpolation between the two through zero."""
    q = np.array(q, float)
    k = np.flatnonzero(~np.isnan(q).any(1))
    if len(k) > 1:
        flip = np.einsum("ij,ij->i", q[k[1:]], q[k[:-1]]) < 0
        q[k[1:]] *= np.where(np.cumsum(flip) % 2, -1.0, 1.0)[:, None]
    return q


def on_grid(mc: pd.DataFrame, hz: float = GRID_HZ) -> pd.DataFrame:
    """The take on a hz grid from its first sample: returned as it is when it is already at hz
    (to float round-off of its own timestamps); otherwise every body's valid samples through a
    cubic spline (positions; quaternions made continuous, then renormalised), a grid sample valid
    where the take's samples on both sides of it are (a dropout stays a dropout)."""
    t = mc["t"].to_numpy(float)
    if len(t) < 2 or abs(float(np.median(np.diff(t))) * hz - 1) < 1e-6:
        return mc
    tg = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * hz + 1e-6)) + 1) / hz
    k = np.clip(np.searchsorted(t, tg, side="right") - 1, 0, len(t) - 2)
    out = {"t": tg}
    bodies = [c[: -len("_valid")] for c in mc.columns if c.endswith("_valid")]
    for b in bodies:
        v = mc[f"{b}_valid"].to_numpy(bool)
        pose = mc[[f"{b}_{f}" for f in POSE_FIELDS]].to_numpy(float, copy=True)
        pose[~v] = np.nan
        pose[:, 3:] = continuous(pose[:, 3:])
        if v.sum() >= 2:
            g = CubicSpline(t[v], pose[v], axis=0)(tg)
            g[:, 3:] /= np.linalg.norm(g[:, 3:], axis=1, keepdims=True)
        else:
            g = np.full((len(tg), len(POSE_FIELDS)), np.nan)
        for j, f in enumerate(POSE_FIELDS):
            out[f"{b}_{f}"] = g[:, j]
        out[f"{b}_valid"] = v[k] & (v[k + 1] | (tg - t[k] < 1e-9))
    return pd.DataFrame(out)


def track(mc: pd.DataFrame, body: str, fields=("x", "y", "z"), *, max_gap_s: float) -> np.ndarray:
    """One body's columns, invalid samples NaN, dropouts up to max_gap_s (the protocol's
    sampling.max_gap_s, as in the resampling) bridged linearly. The limit is in seconds: as
    samples, it counts the track's own median interval, whatever its rate."""
    x = np.column_stack([mc[f"{body}_{f}"].to_numpy() for f in fields])  # a copy; a column each is cheap
    x[~mc[f"{body}_valid"].to_numpy(bool)] = np.nan
    if len(fields) == 4:  # a bridge between q and -q would pass through zero
        x[:] = continuous(x)
    x = bridge(x, gap_frames(mc["t"].to_numpy(), max_gap_s))
    if len(fields) == 4:
        x = x / np.linalg.norm(x, axis=1, keepdims=True)
    return x


def bridge(x: np.ndarray, limit: int) -> np.ndarray:
    """Each column's NaN runs that lie between valid samples, their first `limit` samples filled by
    linear interpolation on the sample number: pandas' DataFrame.interpolate(limit=limit,
    limit_area="inside"), the same np.interp on the same numbers (tests/test_characterize.py), without
    its per-column overhead, which was most of a characterisation job's time. In place; limit < 1
    fills nothing."""
    if limit < 1:
        return x
    idx = np.arange(len(x))
    for col in x.T:  # views: filled in place
        bad = np.isnan(col)
        ok = np.flatnonzero(~bad)
        if len(ok) == 0 or len(ok) == len(col):
            continue
        since = idx - np.maximum.accumulate(np.where(bad, -1, idx))  # samples since the last valid one
        fill = bad & (idx > ok[0]) & (idx < ok[-1]) & (since <= limit)
        col[fill] = np.interp(idx[fill], ok, col[ok])
    return x


def gap_frames(t: np.ndarray, max_gap_s: float) -> int:
    """max_gap_s as a number of samples of the time base t (its median interval); 0 below two."""
    if len(t) < 2:
        return 0
    step = float(np.median(np.diff(t)))
    return int(round(max_gap_s / step)) if step > 0 else 0


def smooth3(x: np.ndarray) -> np.ndarray:
    """Centred 3-sample moving average along time (ends NaN): mocap noise is 0.3 mm per sample."""
    y = np.full(x.shape, np.nan)
    y[1:-1] = (x[:-2] + x[1:-1] + x[2:]) / 3
    return y


def speed(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Speed (m/s) by central differences of the smoothed positions."""
    xs = smooth3(x)
    v = np.full(len(t), np.nan)
    v[1:-1] = np.linalg.norm(xs[2:] - xs[:-2], axis=1) / (t[2:] - t[:-2])
    return v


def tip_speed(mc: pd.DataFrame, max_gap_s: float) -> np.ndarray:
    return speed(track(mc, "tip", max_gap_s=max_gap_s), mc.t.to_numpy())


def bend(q_prox: np.ndarray, q_dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bend magnitude theta (rad) and direction phi (rad, about the hanging axis from +X toward
    +Z, in the proximal frame): the angle between the proximal and distal tangents."""
    tang = qrotate(qmul(qconj(q_prox), q_dist), np.array([0.0, -1.0, 0.0]))
    theta = np.arccos(np.clip(-tang[..., 1], -1.0, 1.0))
    phi = np.arctan2(tang[..., 2], tang[..., 0])
    return theta, phi


def section_bends(mc: pd.DataFrame, max_gap_s: float) -> tuple[np.ndarray, np.ndarray]:
    """theta, phi of S1..S3 over time, each (n, 3)."""
    Q = {b: track(mc, b, ("qw", "qx", "qy", "qz"), max_gap_s=max_gap_s) for b in ("base", "s1", "s2", "tip")}
    th, ph = zip(*(bend(Q[a], Q[b]) for a, b in SECTION_FRAMES))
    return np.stack(th, 1), np.stack(ph, 1)


def section_rates(mc: pd.DataFrame, max_gap_s: float) -> np.ndarray:
    """Bend rate (rad/s) of S1..S3 over time, (n, 3): the angular speed of each section's
    relative rotation (so a bend that swings through straight still counts), smoothed like speed."""
    Q = {b: track(mc, b, ("qw", "qx", "qy", "qz"), max_gap_s=max_gap_s) for b in ("base", "s1", "s2", "tip")}
    t = mc.t.to_numpy()
    out = np.full((len(t), 3), np.nan)
    for s, (a, b) in enumerate(SECTION_FRAMES):
        rel = qmul(qconj(Q[a]), Q[b])
        d = qmul(qconj(rel[:-2]), rel[2:])
        ang = 2 * np.arctan2(np.linalg.norm(d[:, 1:], axis=1), np.abs(d[:, 0]))
        w = np.full(len(t), np.nan)
        w[1:-1] = ang / (t[2:] - t[:-2])
        out[:, s] = smooth3(w[:, None])[:, 0]
    return out


def peak(v: np.ndarray, t: np.ndarray, t_from: float) -> tuple[float, float]:
    """(peak value, its time) from t_from on (NaN if nothing there)."""
    m = (t >= t_from) & ~np.isnan(v)
    if not m.any():
        return float("nan"), float("nan")
    k = np.flatnonzero(m)[np.argmax(v[m])]
    return float(v[k]), float(t[k])
