"""Unit quaternions (w, x, y, z), vectorised over leading axes: the one place the project does
rotation arithmetic (simulated mocap, resampling into the base frame, bend angles)."""

from __future__ import annotations

import numpy as np


def mat_apply(R, p):
    """R p for vectors p (..., 3), in elementwise products and sums: a matrix product goes through
    BLAS, whose kernels (and their last bits) differ between CPUs, and a recording's bytes must not."""
    p = np.asarray(p, float)
    return p[..., :1] * R[:, 0] + p[..., 1:2] * R[:, 1] + p[..., 2:3] * R[:, 2]


def norm3(v):
    """|v| of vectors v (..., 3), elementwise (as mat_apply, no BLAS dot)."""
    v = np.asarray(v, float)
    return np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1] + v[..., 2] * v[..., 2])


def qmul(a, b):
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        -1,
    )


def qconj(q):
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def qrotate(q, v):
    """Rotate vector(s) v by unit quaternion(s) q."""
    qv = np.concatenate([np.zeros(np.shape(v)[:-1] + (1,)), v], -1)
    return qmul(qmul(q, qv), qconj(q))[..., 1:]


def from_rotvec(v):
    v = np.asarray(v, float)
    ang = np.linalg.norm(v, axis=-1, keepdims=True)
    axis = np.divide(v, ang, out=np.zeros_like(v), where=ang > 0)
    return np.concatenate([np.cos(ang / 2), axis * np.sin(ang / 2)], -1)


def to_matrix(q):
    """(..., 4) -> (..., 3, 3) rotation matrices (body to lab)."""
    w, x, y, z = np.moveaxis(np.asarray(q), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )
