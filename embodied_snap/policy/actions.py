"""From six dimensionless outputs to the primitive's commands (paper Eq. 7-8).

Eq. 7 decodes u in [-1, 1] into each action's physical range, the distal slack s3 through a
quadratic map for resolution near zero. Each preload is then limited by the measured directional
workspace in the commanded bearing, rho_i <= 0.9 rho_i_max, and the S1 delay is projected onto
the hardware-validated timing set (Eq. 8).
"""

from __future__ import annotations

import numpy as np

from .networks import ACTIONS


def decode(u: np.ndarray, ranges: dict) -> dict[str, np.ndarray]:
    """Eq. 7: u (N, 6) in ACTIONS order -> {action: (N,)} in ticks, degrees and seconds."""
    out = {}
    for j, a in enumerate(ACTIONS):
        lo, hi = ranges[a]
        f = (np.clip(u[:, j], -1, 1) + 1) / 2
        out[a] = lo + (hi - lo) * (f * f if a == "s3" else f)
    return out


def effective_u(cmds: dict, ranges: dict) -> np.ndarray:
    """The inverse of Eq. 7 on applied commands {action: (N,)}: u (N, 6) in ACTIONS order."""
    cols = []
    for a in ACTIONS:
        lo, hi = ranges[a]
        f = np.clip((np.asarray(cmds[a], float) - lo) / (hi - lo), 0, 1)
        cols.append(2 * (np.sqrt(f) if a == "s3" else f) - 1)
    return np.stack(cols, 1)


def workspace_clamp(act: dict, bearing_deg: np.ndarray, ws: dict, frac: float) -> dict:
    """rho_i <- min(rho_i, frac * rho_i_max(bearing)) from the recorded directional workspace: the
    largest recorded preload per bearing bin (ws: bin_lo_deg, bin_width_deg, rho_max (bins, 3))."""
    k = np.clip(((bearing_deg - ws["bin_lo_deg"]) // ws["bin_width_deg"]).astype(int), 0, len(ws["rho_max"]) - 1)
    rmax = np.asarray(ws["rho_max"], float)[k]
    out = dict(act)
    for i in range(3):
        out[f"rho{i + 1}"] = np.minimum(act[f"rho{i + 1}"], frac * rmax[:, i])
    return out


def project_timing(tau: np.ndarray, timing_set) -> np.ndarray:
    """Eq. 8: t_rel = Pi_T(tau)."""
    return np.clip(tau, *timing_set)
