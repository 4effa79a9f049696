"""Deployment (docs/deployment.md): the manifest, `esnap deploy` and the virtual Dynamixel bus.

Every fault runs the real client (embodied_snap.deploy.client, dynamixel-sdk) against the virtual
bus on a pseudo-terminal, with a manifest whose schedule is short (about 1.5 s a trial). Each ends
with one line naming the cause, the servos' torque off or stopped as read from the bus, every goal
the bus received inside the envelope, and no recording of the aborted trial.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from embodied_snap import protocol
from embodied_snap.deploy import client
from embodied_snap.deploy import commands as C
from embodied_snap.deploy import manifest as MF
from embodied_snap.lineage.checks import deployment_violations
from embodied_snap.policy import geometry, networks
from embodied_snap.twin import model as M
from embodied_snap.twin import truth as TR
from embodied_snap.twin.stepper import Stepper
from embodied_snap.twin.vbus import VirtualBus, crc16, packet, parse, stuff, unstuff

ROOT = Path(__file__).resolve().parent.parent
FAST = dict(hang_s=0.1, settle_s=0.1, s2_delay_s=0.1, after_s1_s=0.2, plan_margin=0.9, carry_s=0.2,
            carry_hold_s=0.1, carry_ticks=300)


def _workspace(rng) -> dict:
    n = np.array([0.0, -1.0, 0.0])
    b = np.deg2rad(rng.uniform(195, 235, 60))
    r, y = rng.uniform(0.45, 0.75, 60), rng.uniform(-0.7, -0.2, 60)
    P = np.stack([r * np.cos(b), y, r * np.sin(b)], 1)
    D = np.tile([0.6, -0.6, 0.5], (60, 1))
    return dict(hanging_axis=n.tolist(), phi0_deg=210.0, delta_str_deg=5.0, n_strikes=60,
                strike_points_m=P.round(5).tolist(), strike_dirs=(D / np.linalg.norm(D, axis=1)[:, None]).tolist(),
                bin_lo_deg=160.0, bin_width_deg=10.0, rho_max=[[3600.0, 3250.0, 3550.0]] * 11)


def _export(d: Path, schedule: dict) -> Path:
    """A manifest exported from a synthetic policy run and workspace, with the given schedule."""
    rng = np.random.default_rng(3)
    cfg = yaml.safe_load(open(ROOT / "config.yaml"))
    ws = _workspace(rng)
    g = geometry.features(np.asarray(ws["strike_points_m"]), np.asarray(ws["hanging_axis"]))
    run = dict(arch="shared", seed=0, n_params=networks.n_params("shared"), selection_reward=0.4,
               selected_generation=3, theta=rng.normal(0, 0.3, networks.n_params("shared")).tolist(),
               norm=dict(mu=g.mean(0).tolist(), sd=g.std(0).tolist()))
    (d / "run.json").write_text(json.dumps(run))
    proto = protocol.params(cfg, "primitive", "rig")
    proto["rig"]["rated_speed_tick_s"] = 30000.0  # a short preload ramp: the test is about the bus
    # generous reply timeout and watchdog: client and bus share a loaded CI machine, which may not run
    # either for tens of ms; every fault is still detected (and named) the same way, only later
    dcfg = dict(cfg["deployment"], schedule=schedule, policy=cfg["policy"], n_placements=3,
                reply_timeout_ms=250, watchdog_ms=1000)
    man = MF.build({"policy_run": d / "run.json"}, run, ws, dict(lever_ticks_per_rad=[2300, 1450, 1440],
                   ceiling_rad_s=[1.3, 2.1, 2.1]), dcfg, proto, {}, {})
    p = d / "manifest.json"
    p.write_text(json.dumps(man))
    return p


@pytest.fixture(scope="module")
def man_path(tmp_path_factory) -> Path:
    """A short schedule: a whole trial in about a second."""
    return _export(tmp_path_factory.mktemp("manifest"), FAST)


@pytest.fixture(scope="module")
def long_man_path(tmp_path_factory) -> Path:
    """FAST with a carry hold of 10 s: a signal sent 0.4 s in lands mid-trial even when a loaded
    machine runs the test seconds late (with FAST alone the client had once finished first)."""
    return _export(tmp_path_factory.mktemp("long_manifest"), dict(FAST, carry_hold_s=10.0))


def _man(p):
    return json.loads(Path(p).read_text())


def _serve_bus(conn, man, faults, rest=None):
    st = Stepper(dict(M.NOMINAL), dict(rate=[3100.0] * 9, tau=[0.03] * 9), 0.001, TR.LATCH)
    bus = VirtualBus(st, man["envelope"]["eeprom_min"], man["envelope"]["eeprom_max"], faults, rest=rest)
    conn.send(bus.start())
    while True:
        cmd = conn.recv()
        if cmd == "now":
            conn.send(bus.now())
            continue
        if cmd == "stop":
            bus.stop()
        with bus._lock:
            conn.send(dict(goals=np.array(bus.goal_log, float).reshape(-1, 4), torque=[s.torque for s in bus.servos],
                           stopped_at=dict(bus.stopped_at), last_rx_t=bus.last_rx_t, closed=bus.closed,
                           rows=np.asarray(st.rows), dt=st.dt))
        if cmd == "stop":
            return


class _Bus:
    """The virtual bus in its own process, as the workflow's rig runs it (the client's polling and the
    bus's physics do not share one interpreter); what it did is read back from it."""

    def __init__(self, man: dict, faults=None, rest=None):
        ctx = mp.get_context("fork")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve_bus, args=(child, man, faults, rest), daemon=True)
        self.state = None

    def __enter__(self):
        self.proc.start()
        self.port = self.conn.recv()
        return self

    def __exit__(self, *exc):
        self.stop()

    def stop(self):
        if not (self.state or {}).get("final"):
            self.conn.send("stop")
            self.state = dict(self.conn.recv(), final=True)
            self.proc.join(10)

    def refresh(self):
        if not (self.state or {}).get("final"):
            self.conn.send("state")
            self.state = self.conn.recv()

    def now(self) -> float:
        self.conn.send("now")
        return self.conn.recv()

    def goals(self):
        return self.state["goals"]

    def torque_states(self):
        return self.state["torque"]

    def __getattr__(self, k):
        if k in ("stopped_at", "last_rx_t", "closed"):
            return self.state[k]
        if k == "stepper":
            return SimpleNamespace(rows=self.state["rows"], dt=self.state["dt"])
        raise AttributeError(k)


def _bus(man: dict, faults=None, rest=None) -> _Bus:
    return _Bus(man, faults, rest)


def _settle(bus, done, within_s=5.0):
    """Wait (at most within_s) until done(bus): on a loaded machine the bus's threads may run late.
    What the tests assert is on the trial clock the bus keeps, not on how late it got there."""
    t_end = time.monotonic() + within_s
    bus.refresh()
    while not done(bus) and time.monotonic() < t_end:
        time.sleep(0.01)
        bus.refresh()


def _all_stopped(bus):
    return set(bus.stopped_at) == set(range(1, 10))


def _stopped_and_stepped_on(bus):
    """Every servo stopped and the (perhaps late) physics 0.1 s past the stop."""
    return _all_stopped(bus) and len(bus.stepper.rows) * bus.stepper.dt > max(bus.stopped_at.values()) + 0.1


def _run(man_path, out, faults=None, target=None, linger=0.05, done=lambda bus: True, rest=None):
    man = _man(man_path)
    with _bus(man, faults, rest) as bus:
        try:
            client.run(man_path, bus.port, target or man["placements"][1]["target_m"], out=out, say=lambda s: None)
            cause = None
        except client.DeployError as e:
            cause = str(e)
        time.sleep(linger)
        _settle(bus, done)
    return cause, bus


def _inside_envelope(man, bus):
    G = bus.goals()
    lo, hi = (np.asarray(man["envelope"][k]) for k in ("goal_min", "goal_max"))
    ids = G[:, 1].astype(int) - 1
    assert np.all((G[:, 2] >= lo[ids]) & (G[:, 2] <= hi[ids]))


def _aborted(out: Path):
    assert not (out / "groups" / "dep_0001").exists()
    assert json.loads((out / "aborted" / "dep_0001.json").read_text())["cause"]


# --- protocol --------------------------------------------------------------------------------------


def test_packet_crc_and_stuffing():
    # Robotis e-manual, Protocol 2.0 PING example: FF FF FD 00 01 03 00 01 19 4E
    assert packet(1, 0x01, b"") == bytes.fromhex("fffffd000103000119 4e".replace(" ", ""))
    assert crc16(bytes.fromhex("fffffd0001030001")) == 0x4E19
    body = b"\x01\xff\xff\xfd\x02"
    assert stuff(body) == b"\x01\xff\xff\xfd\xfd\x02" and unstuff(stuff(body)) == body
    p = packet(7, 0x03, b"\x74\x00\xff\xff\xfd\x00")
    (pid, inst, params, ok), = parse(bytearray(b"\x00junk" + p))[0]
    assert (pid, inst, params, ok) == (7, 0x03, b"\x74\x00\xff\xff\xfd\x00", True)


# --- manifest and commands ---------------------------------------------------------------------------


def test_manifest_checksum_and_schema(man_path):
    import jsonschema

    man = MF.load(man_path)
    jsonschema.validate(man, json.load(open(ROOT / "schemas/deployment_manifest.schema.json")))
    man["policy"]["theta"][0] += 1e-6
    with pytest.raises(MF.ManifestError, match="checksum mismatch"):
        p = man_path.parent / "tampered.json"
        p.write_text(json.dumps(man))
        MF.load(p)


def test_schedule_is_frozen_and_inside_the_envelope(man_path):
    man = _man(man_path)
    for pl in man["placements"]:
        plan = C.plan(man, pl["target_m"])
        assert not plan["goals"].flags.writeable and plan["goals"].dtype.kind == "i"
        ph = plan["phases"]
        assert ph["t_preload"] < ph["t_slack"] < ph["t_s2"] < ph["t_s1"] < ph["t_carry"] < ph["t_end"]
    bad = dict(man, envelope=dict(man["envelope"], goal_max=[10.0] * 9))
    with pytest.raises(C.RefusedTarget, match="outside the envelope"):
        C.plan(bad, man["placements"][0]["target_m"])


def test_deploy_needs_only_numpy_and_dynamixel_sdk(man_path):
    """The lab PC: `esnap deploy` (dry run) loads no torch, pandas, scipy, mujoco, yaml or snakemake."""
    code = ("import sys; from embodied_snap.cli import main; import embodied_snap.deploy.client as c; c._sdk();"
            f"main(['deploy', '--manifest', '{man_path}', '--placement', '1', '--dry-run']);"
            "heavy = {'torch', 'pandas', 'scipy', 'mujoco', 'yaml', 'snakemake', 'matplotlib', 'sklearn'};"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"
    assert "commands: rho1" in out.stdout


# --- a complete trial: open loop, read back >= 50 Hz, written in the rig format ---------------------


def test_complete_trial_is_open_loop_and_recorded(man_path, tmp_path):
    import pandas as pd

    man = _man(man_path)
    cause, bus = _run(man_path, tmp_path)
    assert cause is None
    plan = C.plan(man, man["placements"][1]["target_m"])
    G = bus.goals()
    got = G[G[:, 3] == 1][:, 2].reshape(-1, 9)  # every goal the servos applied, in order
    assert np.array_equal(got, plan["goals"])  # nothing read back changed a command
    sv = pd.read_parquet(tmp_path / "groups/dep_0001/servo.parquet")
    assert np.array_equal(sv[[f"goal_{i}" for i in range(1, 10)]].to_numpy(), plan["goals"])
    assert np.median(np.diff(sv.t)) <= 1 / 50
    meta = json.loads((tmp_path / "groups/dep_0001/meta.json").read_text())
    assert meta["manifest_sha256"] == man["checksum"] and meta["evidence_set"] == "deployment"
    assert not any(bus.torque_states())


# --- safety and faults -------------------------------------------------------------------------------


@pytest.mark.parametrize("faults, cause", [
    ({"no_reply": {"id": 5, "at_s": 0.3}}, "timeout: no reply from servo 5"),
    ({"bad_crc": {"at_s": 0.3}}, "CRC error"),
    ({"hw_error": {"id": 4, "at_s": 0.3}}, "hardware error on servo 4"),
    ({"model": {"id": 2, "number": 1060}}, "servo 2: model number 1060"),
    ({"eeprom": {"id": 3}}, "servo 3: EEPROM position limits"),
])
def test_fault_stops_with_torque_off(man_path, tmp_path, faults, cause):
    man = _man(man_path)
    got, bus = _run(man_path, tmp_path, faults)
    assert got is not None and cause in got and "\n" not in got
    assert not any(bus.torque_states())  # read from the bus
    _inside_envelope(man, bus)
    _aborted(tmp_path)


def test_tampered_manifest_is_refused(man_path, tmp_path):
    man = _man(man_path)
    man["policy"]["theta"][7] *= 1.01
    p = tmp_path / "tampered.json"
    p.write_text(json.dumps(man))
    with _bus(man) as bus:
        with pytest.raises(client.DeployError, match="refused: .*checksum mismatch"):
            client.run(p, bus.port, man["placements"][0]["target_m"], out=tmp_path, say=lambda s: None)
    assert len(bus.goals()) == 0 and not any(bus.torque_states())
    assert not (tmp_path / "groups").exists()


def test_target_outside_the_workspace_is_refused(man_path, tmp_path):
    got, bus = _run(man_path, tmp_path, target=[0.0, -0.1, 0.0])
    assert got.startswith("refused: target") and "outside the workspace" in got
    assert len(bus.goals()) == 0


def test_port_closed_mid_trial(man_path, tmp_path):
    """The adapter is gone: the client says so; the servos' bus watchdog stops them within its period."""
    man = _man(man_path)
    got, bus = _run(man_path, tmp_path, {"close": {"at_s": 0.3}}, linger=man["servos"]["watchdog_ms"] / 1000 + 0.1,
                    done=_all_stopped)
    assert "port closed" in got or "no reply" in got
    assert bus.closed and set(bus.stopped_at) == set(range(1, 10))
    assert max(bus.stopped_at.values()) - bus.last_rx_t <= man["servos"]["watchdog_ms"] / 1000 + 1e-6
    _inside_envelope(man, bus)
    _aborted(tmp_path)


def _subprocess_trial(man_path, tmp_path, sig, done=lambda bus: True):
    man = _man(man_path)
    bus = _bus(man).__enter__()
    try:
        env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")  # its lines as they are said
        # started with SIGINT ignored, as a shell's background job is: the client must stop on it anyway
        proc = subprocess.Popen([sys.executable, "-m", "embodied_snap.cli", "deploy", "--manifest", str(man_path),
                                 "--port", bus.port, "--placement", "2", "--yes", "--out", str(tmp_path)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
        while bus.now() < 0.4 and proc.poll() is None:
            time.sleep(0.01)
        assert proc.poll() is None, f"the client ended before the signal: {proc.communicate()}"
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=20)
        time.sleep(man["servos"]["watchdog_ms"] / 1000 + 0.05)
        _settle(bus, done)
        return proc.returncode, err, bus, man
    finally:
        bus.stop()


def test_sigint_mid_trial(long_man_path, tmp_path):
    rc, err, bus, man = _subprocess_trial(long_man_path, tmp_path, signal.SIGINT)
    assert rc == 1 and "interrupted (SIGINT)" in err and "torque off on all servos" in err
    assert not any(bus.torque_states())
    _inside_envelope(man, bus)
    _aborted(tmp_path)


def test_sigkill_mid_trial_the_watchdog_stops_the_servos(long_man_path, tmp_path):
    rc, _, bus, man = _subprocess_trial(long_man_path, tmp_path, signal.SIGKILL, done=_stopped_and_stepped_on)
    assert rc == -signal.SIGKILL
    period = man["servos"]["watchdog_ms"] / 1000
    assert set(bus.stopped_at) == set(range(1, 10))
    # stopped one watchdog period after the killed client's last packet, and never moved again
    assert max(bus.stopped_at.values()) - bus.last_rx_t <= period + 1e-6
    rows = np.asarray(bus.stepper.rows)
    k = int(max(bus.stopped_at.values()) / bus.stepper.dt) + 1
    assert np.allclose(rows[k:], rows[k])
    _inside_envelope(man, bus)
    assert not (tmp_path / "groups" / "dep_0001").exists()


# --- nothing upstream of the manifest changed after export -------------------------------------------


def test_separation_sees_a_changed_input_or_another_manifest(man_path, tmp_path):
    root = tmp_path
    (root / "results/deployment").mkdir(parents=True)
    man = _man(man_path)
    run = root / "run.json"
    run.write_text(Path(man["inputs"]["policy_run"]["path"]).read_text())
    man["inputs"]["policy_run"]["path"] = "run.json"
    man["checksum"] = MF.checksum(man)
    (root / "results/deployment/manifest.json").write_text(json.dumps(man))
    g = root / "raw_data/deployment/groups/dep_0001"
    g.mkdir(parents=True)
    (g / "meta.json").write_text(json.dumps(dict(manifest_sha256=man["checksum"])))
    assert deployment_violations(root, "raw_data") == ([], 1)
    (g / "meta.json").write_text(json.dumps(dict(manifest_sha256="0" * 64)))
    run.write_text(run.read_text() + " ")
    v, _ = deployment_violations(root, "raw_data")
    assert len(v) == 2 and "changed after the manifest was exported" in v[0] and "ran manifest 000000000000" in v[1]


def test_table2_counts_and_paper_column():
    import pandas as pd

    from embodied_snap.deploy import table2 as D

    df = pd.DataFrame(dict(placement=[1, 1, 2, 3], s2_bend_increase_deg=[120.0, 109.0, 130.0, 111.0],
                           v_peak_mps=[1.2, 0.9, 1.5, 1.0], retrieved=[True, False, False, True],
                           attached=[True, False, True, True], open_loop=[True] * 4))
    s = D.summarize(df, 5, 3, 110.0, 1.0, aborted=1)
    assert (s["preload_reached"], s["fast_snap"], s["retrieved"], s["placements_retrieved"]) == (3, 3, 2, 2)
    assert s["peak_speed_median_mps"] == pytest.approx(1.1) and s["online_correction"] == "none"
    t = D.table2(s, 110.0, 1.0)
    assert t.result.tolist()[0] == "3/5" and t.paper.tolist()[0] == "18/18" and t.paper.tolist()[-1] == "none"
    mixed = df.assign(open_loop=[True, False, True, True])
    assert D.summarize(mixed, 5, 3, 110.0, 1.0, 0)["online_correction"] != "none"


# --- the simulated rig behind the bus: live physics, the block on its support, retrieval ------------


def test_stepper_steps_the_physics_of_sim_run_live():
    """Goals arriving at their times step the same physics as sim.run on the precomputed shafts:
    present position and current come from the simulation (the loop deflects under cable tension)."""
    from embodied_snap.twin import servo as SV
    from embodied_snap.twin import sim

    dt, n, rate = 0.001, 600, np.full(9, 3000.0)
    G = np.array([900.0, 0, 0, 500, 0, 0, 0, 0, 0])
    st = Stepper(dict(M.NOMINAL), dict(rate=rate, tau=[0.03] * 9), dt, TR.LATCH)
    for i in range(9):
        st.set_torque(i, True, 0.0)
        st.set_goal(i, G[i], dt)
    st.advance(n * dt)
    goals = np.tile(G, (n, 1))
    goals[0] = 0.0
    shaft = SV.present_from_goal(goals, dt, rate, np.full(9, 0.03))
    ref = sim.run(dict(M.NOMINAL), shaft, dt, TR.LATCH, rate=rate)
    tr, present = st.finish()
    assert np.array_equal(present, ref.present) and np.array_equal(tr.pos, ref.pos)
    assert np.array_equal(st.present(), ref.present[-1])
    assert present[-1, 0] < shaft[-1, 0] - 1.0  # the loaded loop gives way by its deflection
    assert np.allclose(present[-1], shaft[-1] - SV.deflection(ref.tension[-2]))
    cur = np.mean([st.current_ma() for _ in range(50)], axis=0)
    assert cur[0] > cur[8] + 10.0  # the pulling servo draws the current of its cable's tension


def test_block_stays_on_its_support_until_pulled():
    from embodied_snap.twin import sim
    from embodied_snap.twin.deployment import block_at

    target = block_at([0.3, -0.6, 0.2], [-0.5, 0.3, -0.8])
    arm = sim.Arm(dict(M.NOMINAL, block_mass=TR.BLOCK["mass_kg"]), 0.001, TR.LATCH,
                  scene=sim.Scene(target=target, seal=TR.SEAL, block=TR.BLOCK))
    for _ in range(500):
        arm.step(np.zeros(9))
    tr = arm.trial()
    assert np.abs(tr.target_pos - target["pos"]).max() < 1e-3 and tr.events["released"] is None
    assert np.abs(np.abs(tr.target_quat @ target["quat"]) - 1).max() < 1e-4  # and does not turn
    arm.d.eq_active[arm.support] = 0  # off its support, the block falls
    for _ in range(200):
        arm.step(np.zeros(9))
    assert arm.trial().target_pos[-1, 1] < target["pos"][1] - 0.1


def test_retrieved_is_measured_from_the_motion_capture():
    import pandas as pd

    from embodied_snap.twin.deployment import retrieved

    t = np.arange(0, 2.0, 1 / 240)
    tip = np.stack([0.3 * t, np.full_like(t, -0.5), np.zeros_like(t)], 1)
    stand = np.array([0.2, -0.7, 0.0])

    def frame(block):
        cols = dict(t=t, tip_valid=True, target_valid=True)
        cols.update({f"tip_{a}": tip[:, k] for k, a in enumerate("xyz")})
        cols.update({f"target_{a}": block[:, k] for k, a in enumerate("xyz")})
        return pd.DataFrame(cols)

    carried = np.where((t > 0.5)[:, None], tip + [0.0, -0.2, 0.0], stand)
    assert retrieved(frame(carried))
    assert not retrieved(frame(np.tile(stand, (len(t), 1))))  # never left its support
    dropped = carried.copy()
    dropped[:, 1] -= np.where(t > 1.9, 4.9 * (t - 1.9) ** 2, 0.0)  # falling for the last 0.1 s
    assert not retrieved(frame(dropped))  # the seal let go before the end of the carry


def test_no_placement_is_refused_by_its_own_manifest():
    """A placement keeps its strike point's elevation at the new distance: only points whose placed
    target stays inside the target box are used (else the trial would be refused before it starts)."""
    ws = _workspace(np.random.default_rng(3))
    box = MF.feature_box(ws, 0.0)
    pl = MF.placements(ws, (0.5, 0.7), 91, 40, box)
    g = geometry.features(np.array([p["target_m"] for p in pl]), np.array(ws["hanging_axis"]))
    assert np.all((g >= box["lo"]) & (g <= box["hi"]))


def test_lab_trials_are_indexed_by_esnap_deploy_index(man_path, tmp_path):
    """Lab trials (docs/deployment.md): `esnap deploy-index` puts a complete trial that passes the
    gate into index.csv, and lists an abort record, a trial without the operator's labels and a copy
    of the complete trial under another id (one recording, one trial) in aborted.json with their cause."""
    import shutil

    import pandas as pd

    from embodied_snap.cli import main
    from embodied_snap.twin.deployment import DeploymentSetup, run_trial

    raw = tmp_path / "deployment"
    row = run_trial(man_path, 2, 1, DeploymentSetup(raw=raw, seed=1, n_sessions=12, dt=0.001, speed_mps=1.0))
    assert "cause" not in row, row
    gid = row["group_id"]
    shutil.copytree(raw / "groups" / gid, raw / "groups" / "dep_0090")
    meta_path = raw / "groups/dep_0090/meta.json"
    meta = json.loads(meta_path.read_text())
    meta["group_id"] = "dep_0090"
    del meta["labels"]["retrieved"]  # the operator did not label it
    meta_path.write_text(json.dumps(meta))
    shutil.copytree(raw / "groups" / gid, raw / "groups" / "dep_0092")  # the same take, labelled again
    meta = json.loads((raw / "groups/dep_0092/meta.json").read_text())
    (raw / "groups/dep_0092/meta.json").write_text(json.dumps(dict(meta, group_id="dep_0092")))
    (raw / "aborted").mkdir(exist_ok=True)
    (raw / "aborted/dep_0091.json").write_text(json.dumps(dict(group_id="dep_0091", cause="timeout: no reply")))
    # the bus shares a loaded test machine with the client: a late sync-read is not what this is about
    cfg = yaml.safe_load((ROOT / "config.yaml").read_text())
    cfg["gate"]["max_servo_gap_s"] = 1.0
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(cfg))
    assert main(["deploy-index", "--raw", str(raw), "--configfile", str(tmp_path / "config.yaml"),
                 "--planned", "5"]) == 0
    assert pd.read_csv(raw / "index.csv").group_id.tolist() == [gid]
    ab = json.loads((raw / "aborted.json").read_text())
    causes = {a["group_id"]: a["cause"] for a in ab["aborted"]}
    assert (ab["planned"], ab["recorded"]) == (5, 1) and causes["dep_0091"] == "timeout: no reply"
    assert f"the same bytes as {raw}/groups/{gid}/mocap.parquet of group {gid}" in causes["dep_0092"]
    assert "(rule: one recording, one group)" in causes["dep_0092"]
    assert "labels has no 'retrieved'" in causes["dep_0090"] and "meta.json: group dep_0090" in causes["dep_0090"]
