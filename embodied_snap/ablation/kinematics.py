"""Section bend angles, bend rates, tip speed and the curvature-weighted bend point from the
arm state (paper V-A last paragraph, V-B release rules; docs/ablation.md "Curvature").

The state (resample.STATE_COLUMNS) holds the S1 and S2 section ends and the tip relative to the
base, and the tip axis. The arm is modelled as three constant-curvature sections whose chords are
c1 = s1 - base, c2 = s2 - s1, c3 = tip - s2. The tangent at the base is the measured free-hanging
axis n (the base is clamped), at the tip the tip axis, and at an interior joint the bisector of
the two chords meeting there (for two equal arcs of one circle that is the exact tangent). A
section's bend angle is the angle between its two end tangents (its integrated curvature). The
arc length of a section is its chord length: no rig geometry enters, and the same estimate runs
on predicted and recorded states.
"""

from __future__ import annotations

import numpy as np

S1, S2, TIP, AXIS = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _angle_deg(a, b):
    return np.degrees(np.arccos(np.clip((_unit(a) * _unit(b)).sum(-1), -1.0, 1.0)))


def chords(x: np.ndarray) -> list[np.ndarray]:
    """The three section chords of states x (..., >=12)."""
    return [x[..., S1], x[..., S2] - x[..., S1], x[..., TIP] - x[..., S2]]


def bend_angles(x: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Bend angle (deg) of S1, S2, S3: (..., 3) for states x (..., >=12), hanging axis n (3,)."""
    c = [_unit(v) for v in chords(x)]
    t = [np.broadcast_to(np.asarray(n, float), c[0].shape), _unit(c[0] + c[1]), _unit(c[1] + c[2]),
         x[..., AXIS]]
    return np.stack([_angle_deg(t[i], t[i + 1]) for i in range(3)], -1)


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
