"""Target geometry (paper IV-B, Eq. 5): canonical bearing and the features g = (d, e, r).

Targets are points in the base frame (m, relative to the base b) with a face normal. A target at
bearing beta about the hanging axis n is rotated about n to the canonical bearing
phi0' = phi0 + Delta_str (the model is validated around phi0; Delta_str is the measured offset
between commanded and strike bearing), where the policy sees it.
"""

from __future__ import annotations

import numpy as np

from .. import bearing as BR


def canonical(p: np.ndarray, n: np.ndarray, phi0_strike: float) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 5: p_tilde = R_n(phi0' - beta(p)) p for points p (N, 3); also the rotation angles (N,)."""
    rot = phi0_strike - BR.bearing_deg(p, n)
    return BR.rotate(p, rot, n), rot


def features(q: np.ndarray, n: np.ndarray) -> np.ndarray:
    """g = (d, e, r) (N, 3): distance from the base, elevation along -n (up), horizontal radius."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    along = q @ n
    return np.stack([np.linalg.norm(q, axis=-1), -along, np.linalg.norm(q - along[:, None] * n, axis=-1)], -1)
