"""One acquisition group recorded the lab's way (twin/labrig.py): the group's program played by the
lab's client (deploy.client.drive) over the virtual bus, the servos driving the arm live; the rig's
motion capture and the operator's observations come back from `finish`. Two smoke groups: a
held-base one (the operator pushes the mount from the program's start + its cue) and an attachment
one (the fixed target in the motion capture)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from embodied_snap.acquisition import draws as D
from embodied_snap.acquisition import programs as P
from embodied_snap.deploy import client
from embodied_snap.deploy import controltable as CT
from embodied_snap.deploy import manifest as MF
from embodied_snap.plan import twin_plan
from embodied_snap.twin.labrig import LabRig, LabRigSetup

from paper_protocol import CONFIG as CONFIG_PATH
from paper_protocol import HOLD, PROTO

# The rig's program plays in real time: make test, not make test-fast.
pytestmark = pytest.mark.slow

CONFIG = yaml.safe_load(CONFIG_PATH.read_text())
SEED, DT = CONFIG["seed"], CONFIG["twin"]["dt"]
HELD, ATTACH = "hb_0001", "att_0001"  # hb_0001 pushes during the preload (cue 1.07 s), away from the snap


def _group(gid: str):
    rows = twin_plan(CONFIG["budgets"]["smoke"]["groups"], CONFIG["sessions"]).to_dict("records")
    row = next(r for r in rows if r["group_id"] == gid)
    _, prog, off, _, times, cue = D.draw_group(row, SEED, PROTO, DT)
    group = dict(row, program=prog, target_offset_m=None if off is None else off.tolist(), cue_s=cue)
    goals = np.rint(P.goals_of(prog, 0.01, PROTO)[0]).astype(np.int64)
    goals.setflags(write=False)
    return group, goals, times


def _man(goals: np.ndarray) -> dict:
    lo, hi = goals.min(0), goals.max(0)
    pad = 0.05 * (hi - lo) + 100
    gmin, gmax = np.floor(lo - pad).astype(int), np.ceil(hi + pad).astype(int)
    return dict(servos=dict(ids=list(range(1, 10)), model_number=CT.XM430_W350,
                            operating_mode=CT.EXTENDED_POSITION_MODE, hz=100, watchdog_ms=100,
                            reply_timeout_ms=20, reply_retries=3,
                            start=MF.start(CONFIG["deployment"], PROTO.rig.rated_speed_tick_s)),
                envelope=dict(eeprom_min=(gmin - 500).tolist(), eeprom_max=(gmax + 500).tolist(),
                              goal_min=gmin.tolist(), goal_max=gmax.tolist()))


@pytest.fixture(scope="module")
def played() -> dict:
    out = {}
    for gid in (HELD, ATTACH):
        group, goals, times = _group(gid)
        man = _man(goals)
        env = man["envelope"]
        setup = LabRigSetup(seed=SEED, dt=DT, hold=HOLD, proto=PROTO, eeprom_min=env["eeprom_min"],
                            eeprom_max=env["eeprom_max"])
        rig = LabRig(group, setup)
        with rig as port:
            log, cause, failed = client.drive(man, port, 1000000, goals)
            res = rig.finish(None if cause else float(log[-1, 0]) + 0.005)
        out[gid] = dict(group=group, goals=goals, times=times, log=log, cause=cause, failed=failed, res=res)
    return out


@pytest.mark.parametrize("gid", [HELD, ATTACH])
def test_the_program_plays_and_the_mocap_covers_it(played, gid):
    p = played[gid]
    assert p["cause"] is None and p["failed"] == []
    log, res, mc = p["log"], p["res"], p["res"]["mocap"]
    assert len(log) == len(p["goals"])  # one row per goal ...
    assert np.array_equal(log[:, 1::3], p["goals"])  # ... the program's, in order
    assert not any(res["torque"])  # torque off on every servo at the end, read from the bus
    assert res["first_goal_t"] is not None and 0 <= res["first_goal_t"] < 0.01
    t = mc.t.to_numpy()
    assert t[0] <= max(log[0, 0], 0.0) + 1 / 240 and t[-1] >= log[-1, 0] - 1 / 120
    assert np.all(np.diff(t) > 0) and mc.base_valid.mean() > 0.9 and mc.tip_valid.mean() > 0.9


def _mount(mc, t0, t1):
    """The mount's displacement (m) from where it stood in the 0.3 s before t0, mean over [t0, t1]."""
    t = mc.t.to_numpy()
    xyz = mc[["base_x", "base_y", "base_z"]].to_numpy()
    rest = np.nanmedian(xyz[(t >= t0 - 0.3) & (t < t0)], axis=0)
    return float(np.nanmean(np.linalg.norm(xyz[(t >= t0) & (t < t1)] - rest, axis=1)))


def test_held_base_the_push_moves_the_mount_after_the_cue(played):
    p = played[HELD]
    res, mc = p["res"], p["res"]["mocap"]
    assert res["attached"] is None and res["retrieved"] is None
    hold = res["hold"]
    cue = res["first_goal_t"] + p["group"]["cue_s"]  # the program's clock on the trial clock
    assert hold["base_event_t"] == p["group"]["cue_s"]
    before = _mount(mc, cue - 0.3, cue)  # the same window's rest 0.3 s earlier: the quiet preload
    rise = HOLD["rise_s"]
    during = _mount(mc, cue + rise, cue + rise + hold["hold_s"])  # full force
    # a 10-40 N push on the 8000 N/m mount: millimetres; noise and the preload: a fraction of one
    assert during > 1e-3 and during > 4 * before, (before, during)


def test_attachment_the_fixed_target_is_in_the_mocap(played):
    p = played[ATTACH]
    res, mc = p["res"], p["res"]["mocap"]
    assert isinstance(res["attached"], bool) and isinstance(res["retrieved"], bool)
    assert res["hold"] is None
    if res["attached"]:
        assert 0 < res["t_attach"] < p["log"][-1, 0]
    else:
        assert not res["retrieved"]
    ok = mc.target_valid.to_numpy(bool)
    assert ok.mean() > 0.9
    tgt = mc[["target_x", "target_y", "target_z"]].to_numpy()[ok]
    assert np.all(np.std(tgt, axis=0) < 1e-3)  # fixed: only the mocap's noise
    # where the cup goes: the target stands within the arm's reach of the mount
    base = np.asarray(res["base"]["pos"])
    assert 0.2 < np.linalg.norm(tgt.mean(0) - base) < 1.2
