"""The snap primitive's goal map (paper III-B, Eq. 1), shared by the rig and the pipeline.

The rig (simulated or real) turns a program into servo goals with these functions, and the policy
simulator turns the six policy parameters into the same goals for the dynamics model, so one map
serves both. Nothing here is the simulated rig's: it lives outside `embodied_snap.twin` so that the
pipeline never imports the twin (the import-linter contract in pyproject.toml). The primitive's numbers (the S2 ramp,
the canonical bearing) come from the protocol (embodied_snap.protocol), passed in by the caller.

Everything is in servo ticks and seconds. To bend section p by rho_p / (d_p/k) rad toward bearing
phi, every cable that traverses p takes up rho_p * cos(phi - alpha_k); the antagonists (cos < 0)
pay out 20 % more than that so they never fight the bend. During a release, goals only ever pay
out (a released cable is never taken up again inside a trial), so the antagonists cannot pull
against a latched fold.
"""

from __future__ import annotations

import numpy as np

# Bearings of the three cables of each section about the arm axis (the arm's CAD), and the factor
# by which antagonists pay out beyond their geometric share: the map's shape, not a protocol number.
CABLE_BEARINGS_DEG = (0.0, 120.0, 240.0)
ANTAGONIST_FACTOR = 1.2


def cable_gains(bearing) -> np.ndarray:
    """Take-up per tick of section preload of each cable (..., 3) toward `bearing` (deg, any shape)."""
    c = np.cos(np.deg2rad(np.asarray(bearing, float)[..., None] - np.array(CABLE_BEARINGS_DEG)))
    return np.where(c >= 0, c, ANTAGONIST_FACTOR * c)


def section_goals(rho, bearing_deg: float, slack3: float = 0.0) -> np.ndarray:
    """Nine goals (ticks) for section take-ups rho = (rho1, rho2, rho3) toward a bearing."""
    g = cable_gains(bearing_deg)
    cum = np.cumsum(np.asarray(rho, float))
    w = (cum[:, None] * g[None, :]).reshape(9)
    w[6:9] -= slack3
    return w


def release_goals(rho, s3, bearing, tr, t2, t1, s2_ramp_s: float) -> np.ndarray:
    """Goals (..., T, 9) of the instantaneous primitive at times tr (T,) after its S3 slack: S3 paid
    out by s3, S2 released over s2_ramp_s from t2, S1 at t1. rho (..., 3); s3, bearing, t2, t1 (...).
    Each goal is monotone after the slack, so the never-take-up-again running minimum from the
    full preload W is min(W, goal at the slack, goal now)."""
    rho, e = np.asarray(rho, float), (..., None)
    c = cable_gains(np.asarray(bearing, float))  # (..., 3)
    t2, t1 = np.asarray(t2)[e], np.asarray(t1)[e]
    a2 = np.where(tr < t2, 1.0, np.clip(1.0 - (tr - t2) / s2_ramp_s, 0.0, 1.0))
    a1 = (tr < t1).astype(float)
    a2, a1 = np.broadcast_arrays(a2, a1)
    one = np.ones(a1.shape[:-1] + (1,))
    W = (np.cumsum(rho, -1)[..., :, None] * c[..., None, :]).reshape(*rho.shape[:-1], 1, 9)
    return np.minimum(np.minimum(W, _release(rho, s3, c, one, one)), _release(rho, s3, c, a1, a2))


def _release(rho, s3, c, a1, a2):
    """Goals (..., T, 9) with S1 and S2 held at fractions a1, a2 (..., T) and S3 slack."""
    r1, r2, r3 = (rho[..., k][..., None] for k in range(3))
    cum = np.stack([r1 * a1, r1 * a1 + r2 * a2, r1 * a1 + r2 * a2 + r3 * 0.0], -1)  # (..., T, 3)
    g = (cum[..., :, None] * c[..., None, None, :]).reshape(*cum.shape[:-1], 9)
    g[..., 6:9] -= np.asarray(s3, float)[..., None, None] * 1.0
    return g
