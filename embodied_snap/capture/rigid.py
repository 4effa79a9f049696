"""A body's pose from its markers: the least-squares rigid fit (Kabsch), frame by frame.

For exports that carry markers but no solved rigid body (C3D, a Motive marker set): the layout is
the body's markers in its own frame, and each frame's pose maps it onto the observed markers,
lab = R @ layout + p, minimising the squared distances over the markers seen in that frame.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

MIN_MARKERS = 3  # fewer leave a rotation about their line undetermined


def fit_pose(layout, observed):
    """layout (k, 3) body frame; observed (n, k, 3) lab, NaN where occluded.

    Returns p (n, 3), q (n, 4) as w, x, y, z with w >= 0, valid (n,): a frame with fewer than
    MIN_MARKERS markers seen has a NaN pose and valid False, and residual (n,): the root mean
    square distance of the seen markers from where the fitted pose puts the layout (NaN where not
    valid). A layout that is not the body's, or a marker label on the wrong marker, shows there."""
    layout = np.asarray(layout, float)
    observed = np.asarray(observed, float)
    seen = np.isfinite(observed).all(axis=-1)  # (n, k)
    valid = seen.sum(axis=1) >= MIN_MARKERS
    w = seen[valid].astype(float)[..., None]  # (m, k, 1): an occluded marker weighs nothing
    b = np.where(seen[valid][..., None], observed[valid], 0.0)
    a = np.broadcast_to(layout, b.shape)
    ca = (w * a).sum(1) / w.sum(1)
    cb = (w * b).sum(1) / w.sum(1)
    h = np.einsum("mki,mkj->mij", w * (a - ca[:, None]), b - cb[:, None])  # (m, 3, 3)
    u, _, vt = np.linalg.svd(h)
    v = np.swapaxes(vt, 1, 2)
    ut = np.swapaxes(u, 1, 2)
    # the reflection fix: when V U^T is a reflection (det -1: coplanar markers, or noise), flip the
    # singular vector of the smallest singular value, which gives the best proper rotation
    d = np.where(np.linalg.det(v @ ut) < 0, -1.0, 1.0)
    v[:, :, 2] *= d[:, None]
    r = v @ ut
    p = np.full((len(observed), 3), np.nan)
    q = np.full((len(observed), 4), np.nan)
    p[valid] = cb - np.einsum("mij,mj->mi", r, ca)
    residual = np.full(len(observed), np.nan)
    if valid.any():
        qv = Rotation.from_matrix(r).as_quat(scalar_first=True)
        q[valid] = qv * np.where(qv[:, :1] < 0, -1.0, 1.0)  # q and -q are one rotation: keep w >= 0
        miss = np.einsum("mij,mkj->mki", r, a) + p[valid][:, None] - b  # (m, k, 3), 0 where unseen
        residual[valid] = np.sqrt((w[..., 0] * (miss**2).sum(-1)).sum(1) / w[..., 0].sum(1))
    return p, q, valid, residual
