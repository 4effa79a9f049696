"""Bend-point propagation (paper V-A last paragraph): in strikes, does the curvature-weighted bend
point move along the arm from base to tip? Computed the same way on predicted strikes (the
selected policy's simulated successes) and on the simulated rig's recorded strikes.

A strike's window runs from the S1 release to the peak tip speed after it (both exist on the
model and in every recording with an S1 release); kinematics.travel gives the time-bend-point
correlation of each strike.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.hold import release_row
from ..resample import STATE_COLUMNS
from . import kinematics as KM


def window_correlations(x: np.ndarray, k0: np.ndarray, n: np.ndarray, dt: float) -> np.ndarray:
    """Correlation per strike of states x (N, T, >=12) from step k0 (the first step after release)
    to the peak tip speed after it."""
    v = KM.tip_speed(x, dt)
    bp = KM.bend_point(x, n)
    out = np.full(len(x), np.nan)
    for i in range(len(x)):
        k1 = k0[i] + int(np.argmax(v[i, k0[i]:]))
        ks = np.arange(k0[i], k1 + 1)
        out[i] = KM.travel(ks * dt, bp[i, ks])
    return out


def recorded(frames, metas: dict, n: np.ndarray, after_s1: float, dt: float) -> np.ndarray:
    """Correlation per recorded strike: groups with an S1 release label, from the first frame after
    it to the peak tip speed within after_s1."""
    out = []
    for gid, f in frames.groupby("group_id", sort=True):
        L = metas[gid]["labels"]
        if "t_s1" not in L:
            continue
        t = f["t"].to_numpy()
        i0, i1 = release_row(t, L["t_s1"]) + 1, release_row(t, L["t_s1"] + after_s1)
        if i1 <= i0 + 2:
            continue
        x = f[STATE_COLUMNS].to_numpy(np.float64)[None, i0 - 1:i1 + 1]
        out.append(window_correlations(x, np.array([1]), n, dt)[0])
    return np.asarray(out)
