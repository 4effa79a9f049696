"""Where the arm starts (docs/deployment.md, "Where the arm starts"): `esnap deploy` and `esnap lab
acquire` read every servo's present position before any goal, refuse a servo resting where no
program leaves it, and bring the others to the first goal on a ramp no faster than the manifest's
(plan's) servos.start.ramp_tick_s, aborting with torque off when a cable pulls against the arm.

Three buses: an emulator of nine servos written here (`Arm`: shafts resting at 2048 ticks that go to
a goal at the full profile speed, as an XM430 with Profile Velocity 0 does), the simulated rig's
virtual Protocol 2.0 bus with its servos reading `rest` at the straight hanging arm (the deployment
trial), and the lab's rig for one acquisition group. Also here: one EEPROM home for the plan and the
manifest, the plan named in a plan's refusal, the baud named when no servo answers, and the aborted
marker removed once the group is recorded."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import test_deploy
from simlab import DT, PLAN_CONFIG, SEED

from embodied_snap.cli import main
from embodied_snap.deploy import client
from embodied_snap.deploy import commands as C
from embodied_snap.deploy import controltable as CT
from embodied_snap.deploy import manifest as MF
from embodied_snap.io import read_parquet
from embodied_snap.lab import acquire as LA
from embodied_snap.lab import plan as LP
from embodied_snap.twin.labrig import LabRig, LabRigSetup

from paper_protocol import HOLD, PROTO

man_path = test_deploy.man_path  # the deployment tests' manifest fixture, reused
RATED = 3140.0  # tick/s: the XM430-W350's rated no-load speed (config rig.rated_speed_tick_s)


@pytest.fixture(scope="module")
def man(man_path) -> dict:
    return test_deploy._man(man_path)


class Arm:
    """Nine servos behind a bus, emulated: the shafts rest at `rest` ticks; with torque on each goes to
    its goal first order (30 ms) at up to the rated speed (Profile Velocity 0: the servo's full speed).
    Current: 15 mA idle, plus `ma_per_tick` for every tick a shaft has taken up beyond `taut` (its
    cable pulling the arm). One sync write is one bus cycle; `shafts` holds the shafts after each."""

    def __init__(self, man: dict, rest, taut=None, ma_per_tick=0.5, silent=()):
        sv, env = man["servos"], man["envelope"]
        self.ids, self.baud, self.period = sv["ids"], sv["baud"], 1.0 / sv["hz"]
        self.regs = {i: {CT.OPERATING_MODE: sv["operating_mode"], CT.HARDWARE_ERROR_STATUS: 0,
                         CT.MIN_POSITION_LIMIT: CT.unsigned(env["eeprom_min"][k], 4),
                         CT.MAX_POSITION_LIMIT: CT.unsigned(env["eeprom_max"][k], 4)}
                     for k, i in enumerate(self.ids)}
        self.model, self.silent = sv["model_number"], set(silent)
        self.w = np.broadcast_to(np.asarray(rest, float), (9,)).copy()
        self.goal, self.torque = self.w.copy(), np.zeros(9, bool)
        self.taut = np.full(9, np.inf) if taut is None else np.broadcast_to(np.asarray(taut, float), (9,))
        self.ma_per_tick = ma_per_tick
        self.shafts, self.torque_on_writes, self.goals_written = [self.w.copy()], 0, []

    def ping(self, i):
        if i in self.silent:
            raise client.DeployError(f"timeout: no reply from servo {i} (ping: [TxRxResult] no status packet)")
        return self.model

    def read(self, i, reg):
        if reg == CT.PRESENT_POSITION:
            return CT.unsigned(int(np.rint(self.w[i - 1])), 4)
        return int(self.torque[i - 1]) if reg == CT.TORQUE_ENABLE else self.regs[i][reg]

    def write(self, i, reg, value):
        if reg == CT.TORQUE_ENABLE:
            self.torque[i - 1] = bool(value)
            self.torque_on_writes += bool(value)
            self.goal[i - 1] = self.w[i - 1]  # torque on holds where the shaft is

    def sync_write(self, goals):
        self.goals_written.append(np.array(goals))
        self.goal = np.where(self.torque, goals, self.goal)
        for _ in range(int(round(self.period / 0.001))):  # one cycle at 1 ms
            step = np.clip((self.goal - self.w) * 0.001 / 0.03, -RATED * 0.001, RATED * 0.001)
            self.w = np.where(self.torque, self.w + step, self.w)
        self.shafts.append(self.w.copy())

    def sync_read(self, pos=None, cur=None):
        pos = np.empty(9) if pos is None else pos
        cur = np.empty(9) if cur is None else cur
        pos[:] = np.rint(self.w)
        cur[:] = np.where(self.torque, 15.0 + self.ma_per_tick * np.maximum(self.w - self.taut, 0.0), 0.0)
        return pos, cur

    def drain(self):
        pass

    def torque_off(self):
        self.torque[:] = False
        return []

    def close(self):
        pass


class NoWait:
    """client.Deadlines without sleeping: the emulator's cycles are its sync writes."""

    def __init__(self, period):
        self.period, self.k = period, 0

    def wait(self, k):
        self.k = k

    def now(self):
        return self.k * self.period


def _drive(monkeypatch, man, arm, goals):
    monkeypatch.setattr(client, "Bus", lambda *a, **kw: arm)
    monkeypatch.setattr(client, "Deadlines", NoWait)
    goals = np.asarray(goals, np.int64)
    goals.setflags(write=False)
    started = {}
    log, cause, failed = client.drive(man, "emulated", man["servos"]["baud"], goals, started=started)
    return log, cause, started


def _slow(man: dict, ramp_tick_s: float = 0.1 * RATED) -> dict:
    """The manifest with the ramp at the config's default: 10 % of the rated speed."""
    m = copy.deepcopy(man)
    m["servos"]["start"]["ramp_tick_s"] = ramp_tick_s
    return m


def test_servos_resting_at_2048_come_to_the_first_goal_no_faster_than_the_ramp(monkeypatch, man):
    m = _slow(man)
    arm = Arm(m, rest=2048)
    goals = np.zeros((30, 9))
    log, cause, started = _drive(monkeypatch, m, arm, goals)
    assert cause is None
    step = m["servos"]["start"]["ramp_tick_s"] / m["servos"]["hz"]  # ticks per cycle
    moved = np.abs(np.diff(np.asarray(arm.shafts), axis=0)).max()
    assert moved <= step + 1, f"a shaft moved {moved:.1f} ticks in one cycle, the ramp allows {step:.2f}"
    # the ramp is not in the servo log: the log is the schedule, from where the ramp left the arm
    assert len(log) == len(goals) and np.array_equal(log[:, 1::3], goals)
    assert np.abs(log[0, 2::3]).max() <= 10  # arrived, but for the servo's lag behind the ramp (v tau)
    assert started["present"] == [2048] * 9 and started["ramp_cycles"] == int(np.ceil(2048 / step))
    assert started["first_goal"] == [0] * 9 and len(started["peak_current_ma"]) == 9


def test_a_cable_pulling_on_the_ramp_aborts_with_torque_off(monkeypatch, man):
    m = _slow(man)
    # servo 2 rests paid out 2048 ticks but its cable is taut from -1500: taking it up to 0 pulls the arm
    taut = np.full(9, np.inf)
    taut[1] = -1500.0
    arm = Arm(m, rest=-2048, taut=taut)
    log, cause, started = _drive(monkeypatch, m, arm, np.zeros((30, 9)))
    assert log is None and cause.startswith("servo 2: ") and "mA on the start ramp" in cause and "\n" not in cause
    assert "limit 300 mA" in cause
    assert not arm.torque.any()
    shafts = np.asarray(arm.shafts)
    assert shafts[-1, 1] < -800  # stopped soon after the cable went taut (300 mA at 600 ticks past it)
    assert max(started["peak_current_ma"]) > 300


def test_a_servo_resting_where_no_program_leaves_it_is_refused_before_torque(monkeypatch, man):
    env, tol = man["envelope"], man["servos"]["start"]["tolerance_ticks"]
    rest = np.zeros(9)
    rest[3] = env["eeprom_max"][3] + tol + 1  # servo 4: outside its limits by more than the tolerance
    arm = Arm(man, rest=rest)
    log, cause, _ = _drive(monkeypatch, man, arm, np.zeros((30, 9)))
    assert cause == (f"servo 4: rests at {int(rest[3])} ticks, {tol + 1} outside its EEPROM limits "
                     f"{env['eeprom_min'][3]} .. {env['eeprom_max'][3]} (tolerance {tol}), where no program of "
                     "the manifest leaves it: is its Homing Offset set (the straight hanging arm reads 0), is the "
                     "right servo on id 4?")
    assert arm.torque_on_writes == 0 and arm.goals_written == []
    rest[3] -= 1  # at the tolerance: accepted, and ramped in
    arm = Arm(man, rest=rest)
    assert _drive(monkeypatch, man, arm, np.zeros((30, 9)))[1] is None


def test_a_silent_first_servo_names_the_baud(man):
    with pytest.raises(client.DeployError) as e:
        client.preflight(Arm(man, 0, silent={1}), man)
    assert str(e.value).startswith("timeout: no reply from servo 1 (ping")
    assert f"; no servo answers at {man['servos']['baud']} baud: check the servos' Baud Rate" in str(e.value)
    with pytest.raises(client.DeployError) as e:  # servo 1 answers: the bus's baud is right
        client.preflight(Arm(man, 0, silent={2}), man)
    assert "baud" not in str(e.value)


def test_a_plans_refusal_names_the_plan(man):
    plan = dict(copy.deepcopy(man), format=LP.FORMAT)
    arm = Arm(plan, 0)
    arm.model = 1060
    with pytest.raises(client.DeployError, match=r"^servo 1: model number 1060, the plan says 1020$"):
        client.preflight(arm, plan)
    arm = Arm(man, 0)
    arm.model = 1060
    with pytest.raises(client.DeployError, match=r"^servo 1: model number 1060, the manifest says 1020$"):
        client.preflight(arm, man)


def test_a_manifest_without_start_settings_is_refused_in_one_line(man):
    m = copy.deepcopy(man)
    del m["servos"]["start"]
    with pytest.raises(client.ArgumentError, match=r"^the manifest has no servos.start .*write it again$"):
        client.checked_start(m)


def test_a_recorded_trial_removes_its_aborted_marker(tmp_path):
    client.write_aborted(tmp_path, "dep_0001", "interrupted (SIGINT)", [])
    client.write_aborted(tmp_path, "dep_0002", "interrupted (SIGINT)", [])
    log = np.zeros((3, 28))
    log[:, 0] = [0.0, 0.01, 0.02]
    client.write_trial(tmp_path, dict(group_id="dep_0001"), log)
    assert not (tmp_path / "aborted" / "dep_0001.json").exists()
    assert (tmp_path / "aborted" / "dep_0002.json").exists()  # another group's stays


# --- one EEPROM home: the arm set up for the plan runs the deployment ---------------------------------


@pytest.fixture(scope="module")
def plan_doc():
    """The smoke plan of the config the deployment tests' manifest was exported with (its schedule)."""
    cfg = dict(PLAN_CONFIG, deployment=dict(PLAN_CONFIG["deployment"], schedule=test_deploy.FAST))
    return LP.build(cfg, "smoke")


def test_the_plan_and_the_manifest_want_the_same_eeprom_limits(plan_doc, man):
    assert (plan_doc["envelope"]["eeprom_min"], plan_doc["envelope"]["eeprom_max"]) == \
        (man["envelope"]["eeprom_min"], man["envelope"]["eeprom_max"])
    arm = Arm(plan_doc, 0)  # the servos set up from the plan
    client.preflight(arm, plan_doc)
    client.preflight(arm, man)  # ... pass the deployment's preflight unchanged
    for doc in (plan_doc, man):  # and every goal of either stays inside them
        env = doc["envelope"]
        assert np.all(np.asarray(env["eeprom_min"]) <= env["goal_min"])
        assert np.all(np.asarray(env["eeprom_max"]) >= env["goal_max"])


def test_goals_beyond_the_arms_limits_are_refused_where_the_envelope_is_made():
    limits = MF.arm_limits(PLAN_CONFIG["policy"]["ranges"], 500, 0.05)
    hi = np.asarray(limits["eeprom_max"], float)
    with pytest.raises(ValueError, match=r"^servo 1: goals 0 \.\. \d+ outside the arm's EEPROM limits"):
        MF.widened(np.zeros(9), hi + np.r_[100, np.zeros(8)], 0.0, limits)


# --- the simulated rig's virtual bus: the deployment and an acquisition group ---------------------------


def test_the_deployment_on_the_virtual_bus_ramps_from_where_the_servos_rest(man_path, tmp_path):
    """Servos reading 300 ticks at the straight hanging arm (a Homing Offset 300 off): the shafts move
    to the first goal no faster than the ramp, measured on the simulated shafts; the trial then runs
    its schedule exactly, and the ramp is in meta.json's `start`, not in the servo log."""
    m = test_deploy._man(man_path)
    m["servos"]["start"]["ramp_tick_s"] = 300.0  # the rig's servos reach 3100 tick/s
    m["checksum"] = MF.checksum(m)
    p = tmp_path / "manifest.json"
    p.write_text(json.dumps(m))
    # the physics may run behind the bus on a loaded machine: wait until it has stepped past the ramp
    cause, bus = test_deploy._run(p, tmp_path, rest=300, done=lambda b: len(b.stepper.rows) * b.stepper.dt > 1.2)
    assert cause is None
    plan = C.plan(m, m["placements"][1]["target_m"])
    G = bus.goals()
    rows, dt = np.asarray(bus.stepper.rows), bus.stepper.dt  # the simulated shafts, every dt from the first goal
    near = np.abs(rows + 300).max(1) < 10  # at the first goal: 0 read, -300 on the shaft
    arrive = int(np.argmax(near)) if near.any() else len(rows) - 1
    way = rows[: arrive + 1]
    # speeds over 0.1 s: the goals step every 10 ms, and a cycle the loaded machine delays is caught up
    # at once (client.Deadlines), so over a cycle or two the step can come early
    win = int(round(0.1 / dt))
    speed = np.abs(way - way[np.maximum(np.arange(len(way)) - win, 0)]).max() / 0.1
    assert arrive > 0.9 / dt and speed <= 1.15 * 300, (arrive * dt, speed)
    st = json.loads((tmp_path / "groups/dep_0001/meta.json").read_text())["start"]
    assert st["present"] == [300] * 9 and st["ramp_cycles"] == 100 and len(G) == 9 * (100 + len(plan["goals"]))
    sv = read_parquet(tmp_path / "groups/dep_0001/servo.parquet")
    assert np.array_equal(sv[[f"goal_{i}" for i in range(1, 10)]].to_numpy(), plan["goals"])
    assert not any(bus.torque_states())


def test_an_acquisition_group_ramps_from_where_the_servos_rest(plan_doc, tmp_path):
    """esnap lab acquire through the same door: a servo-calibration group on the lab's simulated rig
    whose servos read -400 at rest. Its goals come to the first goal in ramp steps, the group is
    recorded with its schedule alone in the servo log (the ramp is never read as a burst), and the
    ramp is in meta.json's `start`."""
    path = tmp_path / "plan.yaml"
    LP.write(plan_doc, path)
    entry = next(e for e in plan_doc["groups"] if e["evidence_set"] == "servo_calibration")
    env, got = plan_doc["envelope"], {}
    step = plan_doc["servos"]["start"]["ramp_tick_s"] / plan_doc["servos"]["hz"]

    from contextlib import contextmanager

    @contextmanager
    def rig(e):
        group = dict({k: e[k] for k in ("group_id", "evidence_set", "category", "session", "program")})
        setup = LabRigSetup(seed=SEED, dt=DT, hold=HOLD, proto=PROTO, eeprom_min=env["eeprom_min"],
                            eeprom_max=env["eeprom_max"])
        r = LabRig(group, setup, rest=-400)
        with r as port:
            yield port
            t_end = read_parquet(tmp_path / "out/groups" / e["group_id"] / "servo.parquet")["t"].iloc[-1]
            got.update(r.finish(float(t_end) + 0.005))

    asked = []  # the operator runs the first group and stops the session at the second

    def ask(q):
        asked.append(q)
        return "" if len(asked) == 1 else "q"

    options = LA.AcquireOptions(start=entry["group_id"], session=entry["session"], evidence_set="servo_calibration")
    LA.acquire(path, None, tmp_path / "out", options=options, ask=ask, say=lambda s: None, rig=rig)
    assert LA.recorded(tmp_path / "out", entry["group_id"]) and asked[0].startswith("Enter: run it")
    d = tmp_path / "out/groups" / entry["group_id"]
    goals, _ = LP.group_goals(plan_doc, entry)
    G = got["goals"]
    per_cycle = G[G[:, 3] == 1][:, 2].reshape(-1, 9)  # every goal the servos applied, a row per cycle
    n = len(per_cycle) - len(goals)  # the cycles before the schedule's
    assert np.array_equal(per_cycle[n:], goals)
    way = np.vstack([np.full((1, 9), -400), per_cycle[:n + 1]])  # from rest to the schedule's first goal
    assert np.abs(np.diff(way, axis=0)).max() <= step + 1
    meta = json.loads((d / "meta.json").read_text())
    assert meta["start"]["present"] == [-400] * 9 and meta["start"]["ramp_cycles"] == n == int(np.ceil(400 / step))
    sv = read_parquet(d / "servo.parquet")
    assert np.array_equal(sv[[f"goal_{i}" for i in range(1, 10)]].to_numpy(), goals)
    assert not any(got["torque"])


# --- a plan narrowed to one session or evidence set ----------------------------------------------------


def test_a_plan_narrowed_to_a_session_and_an_evidence_set(plan_doc, tmp_path):
    path = tmp_path / "plan.yaml"
    LP.write(plan_doc, path)
    sessions = sorted({e["session"] for e in plan_doc["groups"]})
    s = sessions[1]
    _, todo, _, _ = LA.checked(path, tmp_path / "out", None, None, session=s)
    assert [e["group_id"] for e in todo] == [e["group_id"] for e in plan_doc["groups"] if e["session"] == s]
    _, todo, _, _ = LA.checked(path, tmp_path / "out", None, None, session=s, evidence_set="held_base")
    assert todo and {(e["session"], e["evidence_set"]) for e in todo} == {(s, "held_base")}
    _, todo, _, _ = LA.checked(path, tmp_path / "out", None, None, evidence_set="attachment")
    assert todo and {e["evidence_set"] for e in todo} == {"attachment"}
    listed = ", ".join(sessions)
    with pytest.raises(LA.LabArgumentError, match=rf"^--session s99: not a session of {path} \({listed}\)$"):
        LA.checked(path, tmp_path / "out", None, None, session="s99")
    with pytest.raises(LA.LabArgumentError, match=r"^--evidence-set nosuch: not an evidence set of .* \(attachment, "):
        LA.checked(path, tmp_path / "out", None, None, evidence_set="nosuch")
    other = next(e["group_id"] for e in plan_doc["groups"] if e["session"] != s)
    with pytest.raises(LA.LabArgumentError, match=rf"^--from {other}: not a group of {path} in session {s} "):
        LA.checked(path, tmp_path / "out", other, None, session=s)


def test_the_cli_refuses_an_unknown_session_in_one_line(plan_doc, tmp_path, capsys):
    path = tmp_path / "plan.yaml"
    LP.write(plan_doc, path)
    port = tmp_path / "ttyFAKE"
    port.write_text("")
    rc = main(["lab", "acquire", "--plan", str(path), "--port", str(port), "--out", str(tmp_path / "out"), "--yes",
               "--session", "nosuch"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "--session nosuch: not a session of" in err
