"""Each acquisition group on its own onto the 50 Hz grid: state x_t (21) and command u_t (9).

Paper IV-A: x_t holds the three tracked body positions, the tip axis and the nine servo
positions; u_t the nine servo goals. Positions are taken relative to the base and expressed in
the base frame, so a re-mounted or re-calibrated base does not change the state of the same arm
shape. The grid is the multiples of 1/hz inside the time both logs cover, so grids of different
groups line up and the same recording always gives the same rows.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .io import read_table
from .quat import to_matrix
from .rawformat import SERVO_IDS, TIP_AXIS_LOCAL, RecordingError, group_paths
from .rawschema import TRACKED_BODIES

STATE_COLUMNS = (
    [f"{b}_{c}" for b in ("s1", "s2", "tip") for c in "xyz"]
    + ["axis_x", "axis_y", "axis_z"]
    + [f"pos_{i}" for i in SERVO_IDS]
)
COMMAND_COLUMNS = [f"goal_{i}" for i in SERVO_IDS]
FRAME_COLUMNS = ["group_id", "t", *STATE_COLUMNS, *COMMAND_COLUMNS]

_POS = ("x", "y", "z")
_QUAT = ("qw", "qx", "qy", "qz")


def _empty_frame() -> pd.DataFrame:
    cols = {"group_id": pd.Series(dtype="str"), "t": pd.Series(dtype="float64")}
    cols.update({c: pd.Series(dtype="float32") for c in STATE_COLUMNS + COMMAND_COLUMNS})
    return pd.DataFrame(cols)


def _columns(path, names: list[str]) -> dict[str, np.ndarray]:
    """Named parquet columns as numpy arrays: no DataFrame on this hot path (~1,100 groups)."""
    table = read_table(path, columns=names)
    return {n: table.column(n).to_numpy() for n in names}


def _track(mocap: dict, body: str, tg: np.ndarray, max_gap_s: float, path, gid: str):
    """Position (n,3) and unit quaternion (n,4) of `body` on the grid, across short dropouts."""
    pos = np.column_stack([mocap[f"{body}_{f}"] for f in _POS]).astype(float)
    quat = np.column_stack([mocap[f"{body}_{f}"] for f in _QUAT]).astype(float)
    ok = mocap[f"{body}_valid"].astype(bool) & np.isfinite(pos).all(1) & np.isfinite(quat).all(1)
    tv, pos, quat = mocap["t"][ok], pos[ok], quat[ok]
    # Spans the grid would be interpolated (or held, at its ends) across: samples outside the
    # grid bracket it as well as samples on it, hence the clip.
    pts = np.concatenate([[tg[0]], np.clip(tv, tg[0], tg[-1]), [tg[-1]]])
    gaps = np.diff(pts)
    # The gate (validate.py) has already rejected any dropout longer than max_gap_s; meeting one
    # here means the recording bypassed or changed after the gate: stop, never drop the group.
    if len(tv) < 2 or gaps.max() > max_gap_s + 1e-9:
        k = int(np.argmax(gaps)) if len(tv) >= 2 else 0
        a, b = (pts[k], pts[k + 1]) if len(tv) >= 2 else (tg[0], tg[-1])
        raise RecordingError(
            path,
            gid,
            f"{body} not tracked for {b - a:.3f} s from t={a:.3f} to t={b:.3f} s",
            f"recording passed the gate (mocap dropout <= {max_gap_s:g} s)",
        )
    # Bracketing valid samples and weights, shared by positions (lerp) and quaternions (nlerp;
    # at mocap rates neighbours are so close that nlerp and slerp agree to far below noise).
    i = np.clip(np.searchsorted(tv, tg, side="right") - 1, 0, len(tv) - 2)
    w = np.clip((tg - tv[i]) / (tv[i + 1] - tv[i]), 0.0, 1.0)[:, None]
    p = pos[i] * (1 - w) + pos[i + 1] * w
    # q and -q are the same rotation: blend towards the one nearer the first sample.
    dot = np.sum(quat[i] * quat[i + 1], axis=1, keepdims=True)
    q1 = np.where(dot < 0, -quat[i + 1], quat[i + 1])
    q = quat[i] * (1 - w) + q1 * w
    return p, q / np.linalg.norm(q, axis=1, keepdims=True)


def resample_group(raw_dir, group_id: str, hz: float, max_gap_s: float) -> pd.DataFrame:
    """One group on the `hz` grid (protocol.GRID_HZ), mocap dropouts up to max_gap_s bridged:
    group_id, t, STATE_COLUMNS, COMMAND_COLUMNS (float32)."""
    paths = group_paths(raw_dir, group_id)
    mocap = _columns(
        paths["mocap"], ["t"] + [f"{b}_{f}" for b in TRACKED_BODIES for f in (*_POS, *_QUAT, "valid")]
    )
    servo = _columns(paths["servo"], ["t"] + [f"{k}_{i}" for i in SERVO_IDS for k in ("present", "goal")])
    tm, ts = mocap["t"], servo["t"]
    t0, t1 = max(tm[0], ts[0]), min(tm[-1], ts[-1])
    tg = np.arange(math.ceil(t0 * hz - 1e-6), math.floor(t1 * hz + 1e-6) + 1) / hz
    if len(tg) == 0:
        return _empty_frame()

    poses = {b: _track(mocap, b, tg, max_gap_s, paths["mocap"], group_id) for b in TRACKED_BODIES}
    p_base, r_base = poses["base"][0], to_matrix(poses["base"][1])
    # R_base^T v for each row: einsum over the lab index j of R[n, j, i].
    to_base = lambda v: np.einsum("nji,nj->ni", r_base, v)  # noqa: E731
    cols = [to_base(poses[b][0] - p_base) for b in ("s1", "s2", "tip")]
    cols.append(to_base(to_matrix(poses["tip"][1]) @ np.asarray(TIP_AXIS_LOCAL)))
    # Present positions are sampled measurements: interpolate. A goal is a step command that
    # holds until the next one: zero-order hold of the last goal sent at or before t.
    last = np.clip(np.searchsorted(ts, tg, side="right") - 1, 0, len(ts) - 1)
    cols.append(np.column_stack([np.interp(tg, ts, servo[f"present_{i}"].astype(float)) for i in SERVO_IDS]))
    cols.append(np.column_stack([servo[f"goal_{i}"][last] for i in SERVO_IDS]))
    df = pd.DataFrame(np.hstack(cols).astype(np.float32), columns=STATE_COLUMNS + COMMAND_COLUMNS)
    df.insert(0, "t", tg)
    df.insert(0, "group_id", pd.Series(group_id, index=df.index, dtype="str"))
    return df


def resample_shard(raw_dir, group_ids, hz: float, max_gap_s: float) -> pd.DataFrame:
    """Groups of a shard, each resampled on its own, one after the other."""
    frames = [resample_group(raw_dir, g, hz, max_gap_s) for g in group_ids]
    return pd.concat(frames, ignore_index=True) if frames else _empty_frame()
