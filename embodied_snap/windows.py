"""Training windows over the resampled frames (paper IV-A), stored compactly.

A window is an anchor row t of one group: history x[t-19..t], commands u[t-19..t+5], targets
x[t+1..t+25], and for the open-loop rollout commands up to u[t+24+5] (the lengths are the
protocol's, config `windows`). Frames are stored once
(X, U) with the anchors as row indices, so overlapping windows cost no copies. Windows never
cross groups: every anchor's whole span lies inside its own group's rows.
"""

from __future__ import annotations

import zipfile

import numpy as np
import pandas as pd

from .files import write_atomic
from .protocol import Windows, window_span
from .resample import COMMAND_COLUMNS, STATE_COLUMNS

TIP_COLUMNS = ["tip_x", "tip_y", "tip_z"]
# Relative tolerance on the grid step inside a group: the resampler writes exact multiples.
_GRID_TOL = 1e-3


def make_windows(frames: pd.DataFrame, windows: Windows) -> dict[str, np.ndarray]:
    """X (N,21), U (N,9), group (N,), group_ids (G,), t (N,), anchors (W,), snap, fast, tip_speed_max (W,),
    and the window lengths, so that training and evaluation read them from the file."""
    history, lookahead, horizon, stride = windows.history, windows.lookahead, windows.horizon, windows.stride
    snap_speed_mps, fast_speed_mps = windows.snap_speed_mps, windows.fast_speed_mps
    # Sorted so that the same groups give the same arrays in whatever order the shards came.
    f = frames.sort_values(["group_id", "t"], kind="stable").reset_index(drop=True)
    group_ids, group = np.unique(f["group_id"].to_numpy(dtype=str), return_inverse=True)
    t = f["t"].to_numpy(np.float64)
    X = f[STATE_COLUMNS].to_numpy(np.float32)
    U = f[COMMAND_COLUMNS].to_numpy(np.float32)
    starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]]) if len(f) else np.array([], int)
    ends = np.r_[starts[1:], len(f)]

    same = group[1:] == group[:-1]
    dt_all = np.diff(t)[same]
    dt = float(np.median(dt_all)) if len(dt_all) else 1.0
    if len(dt_all) and np.abs(dt_all / dt - 1).max() > _GRID_TOL:
        raise ValueError("make_windows: frames are not on one uniform grid within each group")

    before, after = window_span(history, lookahead, horizon)
    anchors = np.concatenate(
        [np.arange(s + before, e - after, stride, dtype=np.int64) for s, e in zip(starts, ends)]
        or [np.zeros(0, np.int64)]
    )
    # Tip speed of each step k -> k+1 (relative to the base); a step across a group boundary is
    # never inside a horizon because every anchor has `after` >= horizon rows of its own group.
    tip = X[:, [STATE_COLUMNS.index(c) for c in TIP_COLUMNS]].astype(np.float64)
    step = np.linalg.norm(np.diff(tip, axis=0), axis=1) / dt
    if len(anchors):
        # Max over steps t..t+H-1, i.e. over the horizon's states x[t+1..t+H] and x_t itself.
        tip_max = np.lib.stride_tricks.sliding_window_view(step, horizon).max(axis=1)[anchors]
    else:
        tip_max = np.zeros(0)
    snap = tip_max >= snap_speed_mps
    return {
        "X": X,
        "U": U,
        "group": group.astype(np.int32),
        "group_ids": group_ids.astype(str),
        "t": t,
        "anchors": anchors,
        "snap": snap,
        "fast": (tip_max >= fast_speed_mps) & ~snap,
        "tip_speed_max": tip_max.astype(np.float32),
        "history": np.int64(history),
        "lookahead": np.int64(lookahead),
        "horizon": np.int64(horizon),
    }


def save_windows(path, arrays: dict) -> None:
    """Write an .npz with fixed member order and timestamps, so equal arrays give equal bytes."""

    def fill(tmp):
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
            for key in sorted(arrays):
                info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                with z.open(info, "w", force_zip64=True) as fh:
                    np.lib.format.write_array(fh, np.asarray(arrays[key]), allow_pickle=False)

    write_atomic(path, fill)  # never leave half a file under the output's name


def load_windows(path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}
