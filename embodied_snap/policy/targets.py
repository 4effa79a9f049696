"""Where the arm can strike, and the simulated target sets drawn from it (paper IV-B, V-A).

The workspace is measured on the training-split dynamics groups only, in the canonical bearing
phi0 (the protocol's; each group rotated about the hanging axis n by phi0 - its commanded bearing):
- the strike cloud: the cup (tip + end effector along the tip axis) at the peak tip speed after the
  S1 release, and the cup's direction of travel there;
- Delta_str: median strike bearing minus commanded bearing;
- the directional workspace: the largest recorded preload rho_i per commanded-bearing bin.
Targets are strike-cloud points jittered and turned to a bearing on the evaluated arc, with their
face normal against the incoming cup (as the rig's operator placed the block). The robustness
variant draws them instead uniformly over the measured workspace (`sample_uniform`). Every set has its
own seed; a target's id is a hash of its coordinates, so disjoint ids mean distinct targets.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pandas as pd
from scipy.spatial import Delaunay

from .. import bearing as BR
from ..cup import cup_from_axis
from ..dynamics.hold import release_row, rotate_states
from ..dynamics.model import AXIS, TIP
from ..resample import STATE_COLUMNS


def workspace(frames: pd.DataFrame, metas: dict, n: np.ndarray, after_s1: float, ee_m: float, phi0_deg: float,
              bin_deg: float = 10.0) -> dict:
    phi0 = float(phi0_deg)  # a float in the JSON, however the config spells it
    pts, dirs, dstr, prog = [], [], [], []
    for gid, f in frames.groupby("group_id", sort=True):
        m = metas[gid]
        L, P = m["labels"], m["program"]
        if "t_s1" not in L or "rho1" not in P:
            continue
        prog.append([P["bearing"], P["rho1"], P["rho2"], P["rho3"]])
        t = f["t"].to_numpy()
        i0, i1 = release_row(t, L["t_s1"]) + 1, release_row(t, L["t_s1"] + after_s1)
        if i1 <= i0 + 1:
            continue
        X = rotate_states(f[STATE_COLUMNS].to_numpy(np.float64)[i0:i1 + 2], phi0 - P["bearing"], n)
        cup = cup_from_axis(X[:, TIP], X[:, AXIS], ee_m)
        v = np.linalg.norm(np.diff(X[:, TIP], axis=0), axis=1)
        k = int(np.argmax(v[:-1]))
        pts.append(cup[k])
        d = cup[k + 1] - cup[k]
        dirs.append(d / np.linalg.norm(d))
        dstr.append((BR.bearing_deg(cup[k], n) - phi0 + 180) % 360 - 180)
    prog = np.asarray(prog)
    lo = float(np.floor(prog[:, 0].min() / bin_deg) * bin_deg)
    nb = int(np.ceil((prog[:, 0].max() - lo) / bin_deg)) or 1
    rmax = np.full((nb, 3), np.nan)
    for b in range(nb):
        sel = (prog[:, 0] >= lo + b * bin_deg) & (prog[:, 0] < lo + (b + 1) * bin_deg)
        if sel.any():
            rmax[b] = prog[sel, 1:].max(0)
    for b in range(nb):  # an empty bin takes its nearest recorded neighbour
        if np.isnan(rmax[b, 0]):
            near = np.flatnonzero(~np.isnan(rmax[:, 0]))
            rmax[b] = rmax[near[np.argmin(np.abs(near - b))]]
    return {
        "hanging_axis": [float(x) for x in n],
        "phi0_deg": phi0,
        "delta_str_deg": float(np.median(dstr)),
        "n_strikes": len(pts),
        "strike_points_m": np.round(np.asarray(pts), 5).tolist(),
        "strike_dirs": np.round(np.asarray(dirs), 5).tolist(),
        "bin_lo_deg": lo,
        "bin_width_deg": bin_deg,
        "rho_max": rmax.tolist(),
    }


def target_id(p: np.ndarray) -> str:
    return hashlib.sha1(np.round(p, 4).tobytes()).hexdigest()[:12]


def sample(ws: dict, n_targets: int, seed: int, arc_deg: float, jitter_m: float) -> pd.DataFrame:
    """n targets: a random strike point + N(0, jitter) per axis, turned about n to a bearing uniform
    on arc_deg centred on the canonical strike bearing; face normal against the strike direction."""
    rng = np.random.default_rng(seed)
    P, D, n = (np.asarray(ws[k], float) for k in ("strike_points_m", "strike_dirs", "hanging_axis"))
    k = rng.integers(0, len(P), n_targets)
    p = P[k] + rng.normal(0, jitter_m, (n_targets, 3))
    turn = rng.uniform(-arc_deg / 2, arc_deg / 2, n_targets)
    return _frame(BR.rotate(p, turn, n), BR.rotate(-D[k], turn, n), n)


def _frame(p: np.ndarray, normal: np.ndarray, n: np.ndarray) -> pd.DataFrame:
    df = pd.DataFrame(np.c_[p, normal], columns=["x", "y", "z", "nx", "ny", "nz"])
    df.insert(0, "bearing_deg", BR.bearing_deg(p, n))
    df.insert(0, "target_id", [target_id(q) for q in p])
    return df


def radius_height(p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """(N, 2): horizontal radius about the hanging axis and height along -n (the features r and e)."""
    along = p @ n
    return np.c_[np.linalg.norm(p - along[:, None] * n, axis=1), -along]


def sample_uniform(ws: dict, n_targets: int, seed: int, arc_deg: float) -> pd.DataFrame:
    """n targets uniform in volume over the measured workspace: the region of (radius, height) that
    the recorded strikes span (their convex hull), swept over arc_deg of bearing centred on the
    canonical strike bearing. Rejection sampling; the radius is accepted with probability r / r_max
    (the volume element of a bearing sweep). The face normal is that of the nearest recorded strike
    in (radius, height), so the block faces the cup as the operator would place it."""
    rng = np.random.default_rng(seed)
    P, D, n = (np.asarray(ws[k], float) for k in ("strike_points_m", "strike_dirs", "hanging_axis"))
    rh = radius_height(P, n)
    hull, lo, hi = Delaunay(rh), rh.min(0), rh.max(0)
    out = np.empty((0, 2))
    while len(out) < n_targets:
        c = lo + (hi - lo) * rng.random((4 * n_targets, 2))
        keep = (hull.find_simplex(c) >= 0) & (rng.random(len(c)) < c[:, 0] / hi[0])
        out = np.r_[out, c[keep]]
    out = out[:n_targets]
    k = np.argmin(((out[:, None, :] - rh[None]) ** 2).sum(-1), axis=1)
    # each point in the bearing plane of its nearest strike, then turned across the arc as `sample` does
    radial = P[k] - (P[k] @ n)[:, None] * n
    p = out[:, :1] * radial / np.linalg.norm(radial, axis=1, keepdims=True) - out[:, 1:] * n
    turn = rng.uniform(-arc_deg / 2, arc_deg / 2, n_targets)
    return _frame(BR.rotate(p, turn, n), BR.rotate(-D[k], turn, n), n)
