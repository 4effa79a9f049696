"""Resampling onto the 50 Hz grid: x_t (21) and u_t (9) as paper IV-A defines them."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from embodied_snap.io import write_parquet
from embodied_snap.quat import to_matrix as quat_to_matrix
from embodied_snap.rawformat import group_paths
from embodied_snap.resample import (
    COMMAND_COLUMNS,
    FRAME_COLUMNS,
    STATE_COLUMNS,
    resample_group,
    resample_shard,
)

from fakerig import expected_state, qaxis, qrot, write_fake_group

T0 = 12.5
GEOM = STATE_COLUMNS[:12]  # s1, s2, tip positions and the tip axis


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    raw = tmp_path_factory.mktemp("resample") / "raw_data"
    write_fake_group(raw, "dyn_0001", duration_s=6.0, seed=0)
    write_fake_group(raw, "dyn_0002", duration_s=2.0, seed=1, t0=40.013)
    return raw


@pytest.fixture(scope="module")
def frame(raw):
    return resample_group(raw, "dyn_0001", 50.0, 0.1)


def test_columns(frame):
    assert len(STATE_COLUMNS) == 21 and len(COMMAND_COLUMNS) == 9
    assert STATE_COLUMNS[:12] == [
        "s1_x",
        "s1_y",
        "s1_z",
        "s2_x",
        "s2_y",
        "s2_z",
        "tip_x",
        "tip_y",
        "tip_z",
        "axis_x",
        "axis_y",
        "axis_z",
    ]
    assert STATE_COLUMNS[12:] == [f"pos_{i}" for i in range(1, 10)]
    assert list(frame.columns) == FRAME_COLUMNS == ["group_id", "t", *STATE_COLUMNS, *COMMAND_COLUMNS]
    assert (frame.group_id == "dyn_0001").all()
    assert frame[STATE_COLUMNS].notna().all().all() and frame[COMMAND_COLUMNS].notna().all().all()


def test_50hz_grid_inside_both_logs(raw, frame):
    t = frame.t.to_numpy()
    np.testing.assert_allclose(np.diff(t), 0.02, atol=1e-9)
    np.testing.assert_allclose(t * 50, np.round(t * 50), atol=1e-6)  # multiples of 1/50 s
    mocap = pd.read_parquet(group_paths(raw, "dyn_0001")["mocap"])
    servo = pd.read_parquet(group_paths(raw, "dyn_0001")["servo"])
    lo, hi = max(mocap.t.iloc[0], servo.t.iloc[0]), min(mocap.t.iloc[-1], servo.t.iloc[-1])
    assert lo <= t[0] < lo + 0.02 and hi - 0.02 < t[-1] <= hi
    assert len(t) == 301  # 6 s of mocap at 12.5..18.5 s


def test_base_frame_geometry_static_arm(tmp_path):
    """A rotated and translated base: x holds the arm's base-frame geometry, nothing of the base pose."""
    raw = tmp_path / "raw"
    write_fake_group(raw, "g_static", duration_s=1.0, static=True, dropouts=())
    f = resample_group(raw, "g_static", 50.0, 0.1)
    # The known geometry: cumulative bends 0.2, 0.45, 0.8 rad towards azimuth phi=0.7 rad.
    lengths, th, phi = (0.324, 0.230, 0.326), np.array([0.2, 0.45, 0.8]), 0.7
    d = np.stack([np.sin(th) * np.cos(phi), -np.cos(th), np.sin(th) * np.sin(phi)], axis=1)
    pts = np.cumsum(d * np.array(lengths)[:, None], axis=0)
    want = np.concatenate([pts.ravel(), d[2]])
    got = f[GEOM].to_numpy(np.float64)
    np.testing.assert_allclose(got, np.tile(want, (len(f), 1)), atol=2e-6)
    # The same arm under an identity base at the origin gives the same state.
    raw2 = tmp_path / "raw2"
    write_fake_group(
        raw2, "g_static", duration_s=1.0, static=True, dropouts=(), base_pos=(0, 0, 0), base_quat=(1, 0, 0, 0)
    )
    np.testing.assert_allclose(resample_group(raw2, "g_static", 50.0, 0.1)[GEOM].to_numpy(np.float64), got, atol=2e-6)


def test_moving_arm_matches_known_geometry_across_dropouts(frame):
    want = expected_state(frame.t.to_numpy() - T0)
    got = frame[GEOM].to_numpy(np.float64)
    # Linear interpolation of a swaying arm across <= 12 lost samples: well under a millimetre.
    np.testing.assert_allclose(got, want, atol=5e-4)
    np.testing.assert_allclose(np.linalg.norm(got[:, 9:12], axis=1), 1.0, atol=1e-5)  # unit axis


def test_quaternion_sign_flips_do_not_matter(tmp_path, frame):
    """q and -q are one rotation; mocap may switch between them from one sample to the next."""
    raw = tmp_path / "raw"
    write_fake_group(raw, "dyn_0001", duration_s=6.0, seed=0)
    p = group_paths(raw, "dyn_0001")["mocap"]
    m = pd.read_parquet(p)
    for b in ("base", "tip"):
        q = [f"{b}_q{c}" for c in "wxyz"]
        m.loc[m.index[1::2], q] *= -1.0
    write_parquet(m, p)
    np.testing.assert_allclose(resample_group(raw, "dyn_0001", 50.0, 0.1)[GEOM], frame[GEOM], atol=1e-6)


def test_quat_to_matrix_agrees_with_quaternion_product():
    q = qaxis(np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81]), np.linspace(-3, 3, 7))
    v = np.array([0.2, -1.0, 0.4])
    np.testing.assert_allclose(quat_to_matrix(q) @ v, qrot(q, v), atol=1e-12)


def test_goals_zero_order_held(raw, frame):
    servo = pd.read_parquet(group_paths(raw, "dyn_0001")["servo"])
    ts = servo.t.to_numpy()
    for t, row in zip(frame.t, frame[COMMAND_COLUMNS].to_numpy()):
        last = servo[ts <= t + 1e-12].iloc[-1]  # the last goal sent at or before t
        np.testing.assert_array_equal(row, last[COMMAND_COLUMNS].to_numpy(float))
    # A step command stays a step: only values that were commanded appear.
    for c in COMMAND_COLUMNS:
        assert set(frame[c].unique()) <= set(servo[c].astype(float).unique())


def test_present_positions_interpolated(raw, frame):
    servo = pd.read_parquet(group_paths(raw, "dyn_0001")["servo"])
    for i in (1, 5, 9):
        want = np.interp(frame.t, servo.t, servo[f"present_{i}"].astype(float))
        np.testing.assert_allclose(frame[f"pos_{i}"], want, rtol=1e-6)


def test_target_dropout_is_not_part_of_state(raw):
    """fakerig loses the target for 0.25 s (> max_gap_s): the target is not in x_t, so no error."""
    m = pd.read_parquet(group_paths(raw, "dyn_0001")["mocap"])
    assert (~m.target_valid).sum() / 240 > 0.1
    resample_group(raw, "dyn_0001", 50.0, max_gap_s=0.1)


def test_short_dropouts_bridged_up_to_max_gap(raw):
    # tip loses 6 samples (gap 7/240 s = 0.029 s); s2 loses 12 (13/240 s = 0.054 s).
    resample_group(raw, "dyn_0001", 50.0, max_gap_s=0.055)
    from embodied_snap.validate import RecordingError

    match = r"group dyn_0001: s2 not tracked for 0\.054 s.*rule: recording passed the gate"
    with pytest.raises(RecordingError, match=match):
        resample_group(raw, "dyn_0001", 50.0, max_gap_s=0.05)


def test_shard_concatenates_groups_each_on_its_own_grid(raw, frame):
    shard = resample_shard(raw, ["dyn_0001", "dyn_0002"], 50.0, 0.1)
    assert list(shard.columns) == FRAME_COLUMNS
    assert list(shard.group_id.unique()) == ["dyn_0001", "dyn_0002"]
    pd.testing.assert_frame_equal(shard[shard.group_id == "dyn_0001"].reset_index(drop=True), frame)
    t2 = shard[shard.group_id == "dyn_0002"].t.to_numpy()
    assert t2[0] == pytest.approx(40.02) and np.allclose(np.diff(t2), 0.02)
    assert len(resample_shard(raw, [], 50.0, 0.1)) == 0


def test_deterministic(raw, frame):
    pd.testing.assert_frame_equal(resample_group(raw, "dyn_0001", 50.0, 0.1), frame)
