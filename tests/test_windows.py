"""Windows over the 50 Hz frames: counts, group boundaries, snap/fast flags, storage."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from embodied_snap.resample import COMMAND_COLUMNS, FRAME_COLUMNS, STATE_COLUMNS, resample_shard
from embodied_snap.windows import load_windows, make_windows, save_windows

from fakerig import write_fake_raw
from paper_protocol import PROTO


def W(**kw):
    """The paper's windows (config `windows`), with some fields changed."""
    return dataclasses.replace(PROTO.windows, **kw)

HZ = 50.0
NEED = 20 + 29  # x[t-19..t] before, u[t+24+5] after: 49 rows for one window


def frames(groups: dict[str, np.ndarray]) -> pd.DataFrame:
    """Frames whose tip moves along x with the given per-step speeds (m/s), one array a group."""
    parts = []
    for k, (gid, speed) in enumerate(groups.items()):
        n = len(speed) + 1
        f = pd.DataFrame(0.0, index=range(n), columns=STATE_COLUMNS + COMMAND_COLUMNS)
        f["tip_x"] = np.r_[0.0, np.cumsum(speed) / HZ]
        f["goal_1"] = np.arange(n) + 1000 * k  # tells rows apart
        f.insert(0, "t", 100.0 * k + np.arange(n) / HZ)
        f.insert(0, "group_id", gid)
        parts.append(f)
    return pd.concat(parts, ignore_index=True)[FRAME_COLUMNS]


def still(n):
    return np.zeros(n - 1)


@pytest.mark.parametrize(
    "n,stride,expected", [(48, 1, 0), (49, 1, 1), (50, 1, 2), (100, 1, 52), (100, 3, 18)]
)
def test_counts_for_known_lengths(n, stride, expected):
    w = make_windows(frames({"a": still(n)}), W(stride=stride))
    assert len(w["anchors"]) == expected
    if expected:
        assert w["anchors"][0] == 19 and w["anchors"][-1] <= n - 30
        assert np.all(np.diff(w["anchors"]) == stride)


def test_shapes_and_dtypes():
    w = make_windows(frames({"a": still(60), "b": still(70)}), W())
    n, nw = 130, (60 - 48) + (70 - 48)
    assert w["X"].shape == (n, 21) and w["X"].dtype == np.float32
    assert w["U"].shape == (n, 9) and w["U"].dtype == np.float32
    assert w["group"].shape == (n,) and list(w["group_ids"]) == ["a", "b"]
    for k in ("anchors", "snap", "fast", "tip_speed_max"):
        assert w[k].shape == (nw,)
    assert w["snap"].dtype == bool and w["fast"].dtype == bool


def test_windows_never_cross_groups():
    w = make_windows(frames({"a": still(55), "b": still(49), "c": still(30), "d": still(80)}), W())
    g, a = w["group"], w["anchors"]
    for k in range(-19, 30):  # every row a window reads: history back, rollout commands on
        assert np.all(g[a + k] == g[a])
    assert np.bincount(g[a], minlength=4).tolist() == [7, 1, 0, 32]
    # Rows within a window are consecutive grid steps of one group.
    assert np.allclose(w["t"][a + 29] - w["t"][a - 19], 48 / HZ)


def test_input_order_does_not_matter():
    f = frames({"a": still(60), "b": still(70)})
    w1 = make_windows(f, W())
    w2 = make_windows(f.sample(frac=1.0, random_state=0), W())
    for k in w1:
        np.testing.assert_array_equal(w1[k], w2[k])


def test_flags_match_known_speeds():
    n = 120
    fast = np.full(n - 1, 0.5)  # 0.5 m/s throughout: every window fast, none snap
    spike = np.full(n - 1, 0.1)
    spike[60] = 2.0  # one 2 m/s step between rows 60 and 61
    w = make_windows(frames({"fast": fast, "slow": np.full(n - 1, 0.1), "spike": spike}), W())
    g, a = w["group"], w["anchors"]
    by = {gid: (g[a] == i) for i, gid in enumerate(w["group_ids"])}
    np.testing.assert_allclose(w["tip_speed_max"][by["fast"]], 0.5, rtol=1e-4)
    assert w["fast"][by["fast"]].all() and not w["snap"][by["fast"]].any()
    assert not (w["fast"] | w["snap"])[by["slow"]].any()
    # The horizon of anchor t covers steps t..t+24 (states x_t..x_{t+25}).
    local = a[by["spike"]] - np.flatnonzero(g == list(w["group_ids"]).index("spike"))[0]
    assert np.array_equal(w["snap"][by["spike"]], (local <= 60) & (60 <= local + 24))
    assert not w["fast"][by["spike"]].any()
    assert not (w["snap"] & w["fast"]).any()


def test_flag_thresholds_follow_arguments():
    w = make_windows(frames({"a": np.full(99, 0.5)}), W(snap_speed_mps=0.4, fast_speed_mps=0.2))
    assert w["snap"].all() and not w["fast"].any()


def test_no_windows_for_short_groups():
    w = make_windows(frames({"a": still(20)}), W())
    assert w["anchors"].shape == (0,) and w["snap"].shape == (0,) and w["X"].shape == (20, 21)


def test_save_load_roundtrip_and_deterministic_bytes(tmp_path):
    w = make_windows(frames({"a": still(60), "b": np.full(69, 1.5)}), W())
    p1, p2 = tmp_path / "a" / "w.npz", tmp_path / "b" / "w.npz"
    save_windows(p1, w)
    save_windows(p2, make_windows(frames({"a": still(60), "b": np.full(69, 1.5)}), W()))
    assert p1.read_bytes() == p2.read_bytes()
    back = load_windows(p1)
    assert set(back) == set(w)
    for k in w:
        np.testing.assert_array_equal(back[k], w[k])
        assert back[k].dtype == np.asarray(w[k]).dtype


def test_from_fakerig_groups(tmp_path):
    raw = tmp_path / "raw"
    write_fake_raw(raw, ("dyn_0001", "dyn_0002"), duration_s=4.0)
    f = resample_shard(raw, ["dyn_0001", "dyn_0002"], 50.0, 0.1)
    w = make_windows(f, W())
    sizes = f.groupby("group_id").size()
    assert len(w["anchors"]) == int((sizes - 48).sum())
    # fakerig's recoil at 3 s reaches > 1 m/s: some snap windows, some fast, most slow.
    assert w["snap"].any() and w["fast"].any() and not (w["snap"] | w["fast"]).all()
