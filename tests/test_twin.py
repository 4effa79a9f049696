"""The simulated rig: recording format, determinism, servo rate limit, cable unilaterality,
phenomena keys. Smoke-sized; no timing assertions."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from embodied_snap import rawformat as RF
from embodied_snap.acquisition import programs as P
from embodied_snap.twin import model as M
from embodied_snap.twin import servo as SV
from embodied_snap.twin import sim
from embodied_snap.twin import truth as TR
from embodied_snap.twin.acquire import acquire_groups
from embodied_snap.twin.phenomena import phenomena

from paper_protocol import HOLD, PROTO

DT = 0.001  # config twin.dt

SEED = 20261123
GROUPS = pd.DataFrame(
    [
        ("cal_0001", "servo_calibration", "burst", "s01"),
        ("att_0002", "attachment", "target", "s02"),
        ("rel_0001", "release_mode", "direct", "s01"),
        ("rel_0013", "release_mode", "ramped", "s01"),
        ("rel_0037", "release_mode", "instantaneous", "s01"),
        ("dly_0003", "delay_sweep", "sweep", "s03"),
        ("dly_0004", "delay_sweep", "sweep", "s04"),
        ("dyn_0001", "dynamics", "free_space", "s01"),
        ("hb_0001", "held_base", "held", "s01"),
    ],
    columns=["group_id", "evidence_set", "category", "session"],
)


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    d = tmp_path_factory.mktemp("raw")
    rows = acquire_groups(GROUPS, d, seed=SEED, proto=PROTO, dt=DT, hold=HOLD, progress=False)
    return d, rows


def _read(raw_dir, gid):
    p = RF.group_paths(raw_dir, gid)
    return pd.read_parquet(p["mocap"]), pd.read_parquet(p["servo"]), RF.read_meta(p["meta"])


def test_index_rows(raw):
    d, rows = raw
    assert [r["group_id"] for r in rows] == list(GROUPS.group_id)
    for r in rows:
        assert set(r) == set(RF.INDEX_COLUMNS)
        assert r["n_mocap"] > 240 and r["n_servo"] > 100


def test_mocap_format(raw):
    d, _ = raw
    for gid in GROUPS.group_id:
        mc, _, meta = _read(d, gid)
        assert list(mc.columns) == RF.mocap_columns()
        assert mc.t.dtype == np.float64
        dt = np.diff(mc.t.to_numpy())
        assert np.all(dt > 0)
        assert np.allclose(dt, 1 / RF.MOCAP_HZ, atol=1e-9)
        for b in RF.BODIES:
            v = mc[f"{b}_valid"]
            assert v.dtype == bool
            pose = mc[[f"{b}_{f}" for f in RF.POSE_FIELDS]].to_numpy()
            assert pose.dtype == np.float64
            assert np.all(np.isnan(pose[~v.to_numpy()]))
            assert not np.any(np.isnan(pose[v.to_numpy()]))
            q = pose[v.to_numpy(), 3:]
            assert np.allclose(np.linalg.norm(q, axis=1), 1, atol=1e-9)
        has_target = meta["evidence_set"] in ("attachment", "delay_sweep")
        assert mc.target_valid.any() == has_target
        # sub-millimetre noise and occasional dropouts, never a lost arm
        assert 0.9 < mc.tip_valid.mean() <= 1.0


def test_straight_arm_is_identity_and_hangs_down(raw):
    d, _ = raw
    mc, _, meta = _read(d, "cal_0001")
    first = mc[mc.tip_valid & mc.base_valid].iloc[0]
    axis = np.array(meta["axis"])
    assert abs(np.linalg.norm(axis) - 1) < 1e-9 and axis[1] < -0.99
    tip = first[["tip_x", "tip_y", "tip_z"]].to_numpy(float)
    base = first[["base_x", "base_y", "base_z"]].to_numpy(float)
    assert abs(np.linalg.norm(tip - base) - sum(M.NOMINAL["sec_len"])) < 0.01
    # hanging tip: its orientation is the base's (calibration rotation only)
    q = first[["tip_qw", "tip_qx", "tip_qy", "tip_qz"]].to_numpy(float)
    qb = first[["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy(float)
    assert abs(abs(q @ qb) - 1) < 1e-3


def test_servo_format(raw):
    d, _ = raw
    for gid in GROUPS.group_id:
        _, sl, _ = _read(d, gid)
        assert list(sl.columns) == RF.servo_columns()
        dt = np.diff(sl.t.to_numpy())
        assert np.all(dt > 0)
        assert 0.008 < np.median(dt) < 0.012 and dt.std() > 5e-4  # about 100 Hz, jittered
        for i in RF.SERVO_IDS:
            assert sl[f"goal_{i}"].dtype == np.int64 and sl[f"present_{i}"].dtype == np.int64
            assert sl[f"current_{i}"].dtype == np.float64


def test_meta_keys(raw):
    d, _ = raw
    for gid in GROUPS.group_id:
        _, _, meta = _read(d, gid)
        for k in (
            "group_id",
            "evidence_set",
            "category",
            "session",
            "recorded_at",
            "base",
            "axis",
            "program",
            "labels",
        ):
            assert k in meta
        assert set(meta["base"]) == {"pos", "quat"}
        if meta["evidence_set"] in ("attachment", "delay_sweep"):
            assert isinstance(meta["labels"]["attached"], bool)
            for k in ("rho1", "rho2", "rho3", "s3", "dphi", "tau", "bearing"):
                assert k in meta["program"]
        if meta["evidence_set"] == "held_base":
            assert "base_event_t" in meta["labels"]


def test_same_seed_same_bytes_and_group_independence(raw, tmp_path):
    d, _ = raw
    pick = GROUPS[GROUPS.group_id.isin(["dly_0004", "rel_0037"])]
    # alone, in another order and another directory: identical files
    acquire_groups(pick.iloc[::-1], tmp_path, seed=SEED, proto=PROTO, dt=DT, hold=HOLD, progress=False)
    for gid in pick.group_id:
        for name in RF.GROUP_FILES:
            a = (RF.group_dir(d, gid) / name).read_bytes()
            b = (RF.group_dir(tmp_path, gid) / name).read_bytes()
            assert a == b, (gid, name)
    other = tmp_path / "other"
    acquire_groups(pick.iloc[:1], other, seed=SEED + 1, proto=PROTO, dt=DT, hold=HOLD, progress=False)
    gid = pick.group_id.iloc[0]
    assert (RF.group_dir(d, gid) / "mocap.parquet").read_bytes() != (
        RF.group_dir(other, gid) / "mocap.parquet"
    ).read_bytes()


def test_servo_rate_limit():
    rng = np.random.default_rng(0)
    dt = 0.001
    goals = np.repeat(rng.uniform(-9000, 9000, (12, 9)), 300, axis=0)
    sv = TR.servo_params(SEED)
    w = SV.present_from_goal(goals, dt, np.array(sv["rate"]), np.array(sv["tau"]))
    rate = np.abs(np.diff(w, axis=0)) / dt
    assert rate.max() <= SV.RATE_RATED + 1e-6
    assert rate.max() > 0.9 * SV.RATE_RATED  # and the ceiling is reached on big steps
    # a small step is a first-order lag: 63 % after about tau
    small = np.zeros((400, 9))
    small[100:] = 50.0
    w = SV.present_from_goal(small, dt, np.full(9, 3000.0), np.full(9, 0.03))
    assert 0.55 < w[130, 0] / 50 < 0.7


def test_logged_present_respects_rate_limit(raw):
    d, _ = raw
    _, sl, _ = _read(d, "rel_0037")
    t = sl.t.to_numpy()
    for i in RF.SERVO_IDS:
        w = sl[f"present_{i}"].to_numpy(float)
        assert np.all(np.abs(np.diff(w)) <= SV.RATE_RATED * np.diff(t) + 2.0)


def test_cables_only_pull():
    """A probe through preload and release: cable tension never negative, and a cable
    commanded slack carries nothing (it does not push the arm back)."""
    dt = 0.001
    goals, times = P.primitive(dict(P.OPERATING, tau=0.5), PROTO.primitive.phi0_deg, dt, PROTO)
    goals = goals[: int((times["t_s1"] + 0.4) / dt)]
    pres = SV.present_from_goal(goals, dt, np.full(9, 3000.0), np.full(9, 0.03))
    tr = sim.run(dict(M.NOMINAL), pres, dt, TR.LATCH)
    assert tr.tension.min() >= 0.0
    assert np.all(tr.present <= pres + 1e-9)  # the load only ever deflects a loop toward paying out
    assert tr.tension.max() > 5.0  # they do pull
    # antagonists are paid out: slack (zero tension) while the arm is bent
    i = int((times["t_slack"] - 0.1) / dt)
    assert np.sum(tr.tension[i] == 0.0) >= 3
    # the straight arm with every cable paid out: no force at all
    pres = np.full((300, 9), -500.0)
    tr = sim.run(dict(M.NOMINAL), pres, dt, TR.LATCH)
    assert np.all(tr.tension == 0.0)


def test_truth_is_per_session():
    a = TR.truth(SEED, 3)
    b = TR.truth(SEED, 12)
    assert a["sessions"]["s02"] == b["sessions"]["s02"]
    assert a["sessions"]["s01"] != a["sessions"]["s02"]
    assert a["lever_ticks_per_rad"] == [2351.0, 1411.0, 1390.0]


def test_phenomena_keys(raw):
    d, _ = raw
    ph = phenomena(d, GROUPS, PROTO)
    for k in (
        "direct_release_tip_speed_mps",
        "snap_tip_speed_mps",
        "snap_section_rate_ratio",
        "instant_release_fraction_over_1mps",
        "delay_sweep_best_tau_s",
        "delay_sweep_attach_le_030",
        "delay_sweep_attach_ge_045",
        "attach_below_1mps",
    ):
        assert k in ph
    assert len(ph["snap_section_rate_ratio"]) == 3


def test_servo_loop_deflects_with_tension():
    """The position loop gives way under the cable's load: the deflection grows with the tension
    (T r / K_LOOP), saturates at the stall torque, and in the physics loop the present position is
    the unloaded response minus it."""
    T = np.array([0.0, 5.0, 10.0, 20.0, 40.0, 1e4])
    d = SV.deflection(T)
    assert d[0] == 0.0 and np.all(np.diff(d[:-1]) > 0)
    assert 2.0 < SV.deflection(10.0) < 6.0  # a few ticks at 10 N
    assert d[-1] == pytest.approx(SV.STALL_NM / SV.K_LOOP)  # saturates: the gearbox holds beyond
    dt = 0.001
    goals = np.zeros((1500, 9))
    goals[200:, 0] = 2500.0  # one S1 cable pulls and holds
    shaft = SV.present_from_goal(goals, dt, np.full(9, 3000.0), np.full(9, 0.03))
    tr = sim.run(dict(M.NOMINAL), shaft, dt, TR.LATCH)
    lag = shaft[:, 0] - tr.present[:, 0]
    hold = slice(1000, None)  # settled: the loop sits at its deflection
    np.testing.assert_allclose(lag[hold], SV.deflection(tr.tension[hold.start - 1 : -1, 0]), atol=1e-6)
    assert lag[-1] > 1.0 and tr.tension[-1, 0] > 3.0
    # loaded, the loop still never exceeds its rate ceiling
    assert np.abs(np.diff(tr.present, axis=0)).max() / dt <= SV.RATE_RATED + 1e-6


def test_held_base_force_moves_the_mount_and_shows_in_the_residual():
    """A hold on the mount (external force) moves the base on its spring, the arm swings, the
    cable loads change and the S1 loops' present positions leave their unloaded response."""
    from embodied_snap.twin.acquire import hold_wrench

    dt = 0.001
    goals, times = P.primitive(dict(P.OPERATING, tau=0.5), PROTO.primitive.phi0_deg, dt, PROTO)
    goals = goals[: int(times["t_s2"] / dt)]
    shaft = SV.present_from_goal(goals, dt, np.full(9, 3000.0), np.full(9, 0.03))
    t = np.arange(1, len(goals) + 1) * dt
    t_e = times["t_slack"] - 0.6
    hold = dict(HOLD, mount_force_n=[30.0, 30.0], hold_s=[0.3, 0.3])
    w, prog = hold_wrench(t, t_e, hold, np.random.default_rng(0))
    quiet = sim.run(dict(M.NOMINAL), shaft, dt, TR.LATCH)
    held = sim.run(dict(M.NOMINAL), shaft, dt, TR.LATCH, wrench=w)
    before = t < t_e
    np.testing.assert_allclose(held.present[before], quiet.present[before])
    moved = np.linalg.norm(held.base - quiet.base, axis=1)
    assert moved[before].max() == 0.0 and 1e-3 < moved.max() < 0.02  # mm, not cm
    # the servo-position residual (loaded minus unloaded) changes during the event
    dres = np.abs((held.present - quiet.present)[:, :3]).max(1)
    assert dres[before].max() == 0.0 and dres.max() > 0.3  # a fraction of a tick to ticks: the stiff loop


def test_ramped_release_latches_when_fast_and_is_dragged_when_slow():
    """Fig. 2b: a release ramped over 1 s still latches the fold and snaps; over 6 s the curl opens
    too slowly to hook, nothing latches and the servos drag the arm open below 1 m/s."""
    dt = 0.001
    out = {}
    for ramp in (1.0, 6.0):
        goals, times = P.primitive(dict(P.OPERATING, tau=0.55), PROTO.primitive.phi0_deg, dt, PROTO, ramp_s=ramp)
        shaft = SV.present_from_goal(goals, dt, np.full(9, 3000.0), np.full(9, 0.03))
        tr = sim.run(dict(M.NOMINAL), shaft, dt, TR.LATCH)
        v = np.linalg.norm(np.diff(tr.pos[:, 2], axis=0), axis=1) / dt
        out[ramp] = (tr.events["latch_on"] is not None, np.convolve(v, np.ones(8) / 8, "same").max())
    assert out[1.0][0] and out[1.0][1] > PROTO.thresholds.attach_speed_mps
    assert not out[6.0][0] and out[6.0][1] < PROTO.thresholds.attach_speed_mps


def test_short_delay_snaps_reach_the_face_too_slowly_to_seal():
    """Paper III-B: tau <= 0.30 s gives no attachment, tau >= 0.45 s does. Two sweep trials of the
    paper budget (config seed): at tau 0.30 s the cup meets the face at ~1.0 m/s and bounces; at
    0.45 s it arrives at ~1.8 m/s and seals."""
    from embodied_snap.twin.acquire import simulate_group

    out = {}
    for gid, session in (("dly_0024", "s12"), ("dly_0003", "s03")):
        row = dict(group_id=gid, evidence_set="delay_sweep", category="sweep", session=session)
        meta, _, _ = simulate_group(row, SEED, PROTO, DT, HOLD)
        out[meta["program"]["tau"]] = meta["labels"]["attached"]
    assert out == {0.30: False, 0.45: True}
