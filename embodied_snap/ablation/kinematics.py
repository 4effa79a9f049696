"""Section bend angles, bend rates, tip speed and the curvature-weighted bend point from the
arm state (paper V-A last paragraph, V-B release rules; docs/ablation.md "Curvature").

The state (resample.STATE_COLUMNS) holds the S1 and S2 section ends and the tip relative to the
base, and the tip axis. The arm is modelled as three constant-curvature sections joined without a
kink (piecewise constant curvature), with chords c1 = s1 - base, c2 = s2 - s1, c3 = tip - s2. The
base is clamped, so S1 starts along the measured free-hanging axis n. A circular arc's chord
bisects its end tangents, so each section's end tangent is its start tangent reflected about the
chord, t_i = 2 (t_{i-1} . c_i) c_i - t_{i-1}, and its bend angle (integrated curvature) is twice
the angle between start tangent and chord. This is exact for constant-curvature sections and needs
no rig geometry: the arc length of a section is taken as its chord length (an arc of up to 90 deg
is at most 11 % longer), so the same estimate runs on predicted and recorded states.
"""

from __future__ import annotations

import numpy as np

S1, S2, TIP = slice(0, 3), slice(3, 6), slice(6, 9)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _angle_deg(a, b):
    return np.degrees(np.arccos(np.clip((_unit(a) * _unit(b)).sum(-1), -1.0, 1.0)))


def chords(x: np.ndarray) -> list[np.ndarray]:
    """The three section chords of states x (..., >=12)."""
    return [x[..., S1], x[..., S2] - x[..., S1], x[..., TIP] - x[..., S2]]


def bend_angles(x: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Bend angle (deg) of S1, S2, S3: (..., 3) for states x (..., >=9), hanging axis n (3,)."""
    t = np.broadcast_to(_unit(np.asarray(n, float)), x[..., S1].shape)
    out = []
    for c in chords(x):
        c = _unit(c)
        out.append(2 * _angle_deg(t, c))
        t = 2 * (t * c).sum(-1, keepdims=True) * c - t  # reflection about the chord: the end tangent
    return np.stack(out, -1)


def rates(y: np.ndarray, dt: float) -> np.ndarray:
    """|dy/dt| along the time axis -2 of y (..., T, k) -> (..., T, k); entry k is the backward
    difference (k-1 -> k), so a rate is known at the step it is measured; entry 0 is 0."""
    d = np.abs(np.diff(y, axis=-2)) / dt
    return np.concatenate([np.zeros_like(d[..., :1, :]), d], -2)


def tip_speed(x: np.ndarray, dt: float) -> np.ndarray:
    """Tip speed (m/s) (..., T), backward difference as in `rates`."""
    v = np.linalg.norm(np.diff(x[..., TIP], axis=-2), axis=-1) / dt
    return np.concatenate([np.zeros_like(v[..., :1]), v], -1)


def bend_point(x: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Curvature-weighted bend point (..., T) as a fraction of the arm's arc length: the mean of the
    section midpoints' arc lengths weighted by each section's bend angle (sum theta_i s_i /
    sum theta_i, the discrete form of int kappa s ds / int kappa ds)."""
    theta = bend_angles(x, n)
    L = np.stack([np.linalg.norm(c, axis=-1) for c in chords(x)], -1)
    mid = np.cumsum(L, -1) - L / 2
    w = np.maximum(theta.sum(-1), 1e-9)
    return (theta * mid).sum(-1) / w / L.sum(-1)


def travel(t: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of time and bend point over one strike (NaN if either is constant);
    the bend point moves distally when it is positive."""
    if len(t) < 3 or np.std(b) == 0 or np.std(t) == 0:
        return float("nan")
    return float(np.corrcoef(t, b)[0, 1])


def travel_stats(corrs) -> dict:
    """Fraction of strikes whose bend point moves distally (correlation > 0) and the mean
    correlation, over the strikes where it is defined."""
    c = np.asarray(corrs, float)
    c = c[np.isfinite(c)]
    return dict(n=int(len(c)), distal_fraction=float((c > 0).mean()) if len(c) else None,
                mean_correlation=float(c.mean()) if len(c) else None)
