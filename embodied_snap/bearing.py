"""Bearings about the arm's measured free-hanging axis n (paper IV-B, Eq. 5).

Positions are in the base frame (metres, relative to the base). The bearing of a point is its angle
about n, measured from the base x axis projected off n, in the rig's convention: with n = -y a
bearing phi points along (cos phi, 0, sin phi). Rotating by `deg` about n turns bearing phi into
phi + deg. The hold model and the policy share these, so a command's bearing means one thing.
"""

from __future__ import annotations

import numpy as np


def frame(n: np.ndarray) -> np.ndarray:
    """(3, 3) rows e_x, n, e_z: e_x is the base x axis projected off n, e_z = n x e_x."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    ex = np.array([1.0, 0.0, 0.0]) - n[0] * n
    ex /= np.linalg.norm(ex)
    return np.stack([ex, n, np.cross(n, ex)])


def bearing_deg(p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Bearing (deg, [0, 360)) of points p (..., 3) about n."""
    F = frame(n)
    return np.degrees(np.arctan2(p @ F[2], p @ F[0])) % 360.0


def rotation(deg, n: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) about n by deg (Rodrigues); bearing phi -> phi + deg."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    a = np.deg2rad(np.asarray(deg, float))[..., None, None]
    K = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * (K @ K)


def rotate(v: np.ndarray, deg, n: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) about n by deg (broadcast over leading axes of deg)."""
    return np.einsum("...ij,...j->...i", rotation(deg, n), v)
