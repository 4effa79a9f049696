"""The deployment's safety checks at their edges (issue 27, item 4), without a bus process: the
preflight's refusals one servo and one field at a time, the bus's result/error checks, torque-off,
the envelope at its bounds and the target box. Expected values are the control table's and the
manifest's own numbers, written out; the end-to-end versions are tests/test_deploy.py."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
import test_deploy

from embodied_snap import bearing as BR
from embodied_snap.deploy import client
from embodied_snap.deploy import commands as C
from embodied_snap.deploy import controltable as CT
from embodied_snap.policy import geometry

man_path = test_deploy.man_path  # the deployment tests' manifest fixture, reused


@pytest.fixture(scope="module")
def man(man_path) -> dict:
    return test_deploy._man(man_path)


# --- preflight: one servo, one field wrong at a time -------------------------------------------------


class FakeBus:
    """Answers ping and register reads from a table; the servo ids and values are the manifest's."""

    def __init__(self, man, **wrong):
        sv, env = man["servos"], man["envelope"]
        self.regs = {}
        for k, i in enumerate(sv["ids"]):
            self.regs[i] = {"model": sv["model_number"], CT.OPERATING_MODE: sv["operating_mode"],
                            CT.MIN_POSITION_LIMIT: CT.unsigned(int(env["eeprom_min"][k]), 4),
                            CT.MAX_POSITION_LIMIT: CT.unsigned(int(env["eeprom_max"][k]), 4),
                            CT.HARDWARE_ERROR_STATUS: 0}
        for (i, reg), v in wrong.get("set", {}).items():
            self.regs[i][reg] = v
        self.asked = []

    def ping(self, i):
        self.asked.append((i, "ping"))
        return self.regs[i]["model"]

    def read(self, i, reg):
        self.asked.append((i, reg))
        return self.regs[i][reg]


def test_preflight_passes_the_manifests_servos(man):
    bus = FakeBus(man)
    client.preflight(bus, man)
    ids = man["servos"]["ids"]
    assert [i for i, what in bus.asked if what == "ping"] == ids  # every servo, in order
    assert {what for _, what in bus.asked} == {"ping", CT.OPERATING_MODE, CT.MIN_POSITION_LIMIT,
                                               CT.MAX_POSITION_LIMIT, CT.HARDWARE_ERROR_STATUS}


def test_preflight_refuses_each_wrong_field_on_the_last_servo(man):
    sv, env = man["servos"], man["envelope"]
    i, k = sv["ids"][-1], len(sv["ids"]) - 1
    lo, hi = int(env["eeprom_min"][k]), int(env["eeprom_max"][k])
    cases = [
        ({(i, "model"): 1060}, rf"^servo {i}: model number 1060, the manifest says {sv['model_number']}$"),
        ({(i, CT.OPERATING_MODE): 3}, rf"^servo {i}: operating mode 3, the manifest says {sv['operating_mode']}$"),
        ({(i, CT.MIN_POSITION_LIMIT): CT.unsigned(lo + 1, 4)},
         rf"^servo {i}: EEPROM position limits {lo + 1} \.\. {hi}, the manifest says {lo} \.\. {hi}$"),
        ({(i, CT.MAX_POSITION_LIMIT): CT.unsigned(hi - 1, 4)},
         rf"^servo {i}: EEPROM position limits {lo} \.\. {hi - 1}, the manifest says {lo} \.\. {hi}$"),
        ({(i, CT.HARDWARE_ERROR_STATUS): 0x20}, rf"^servo {i}: hardware error status 0x20 before the trial$"),
        ({(i, CT.HARDWARE_ERROR_STATUS): 0x01}, rf"^servo {i}: hardware error status 0x01 before the trial$"),
    ]
    for wrong, msg in cases:
        with pytest.raises(client.DeployError, match=msg):
            client.preflight(FakeBus(man, set=wrong), man)


def test_preflight_compares_each_servo_with_its_own_limits(man):
    """Servo k's EEPROM limits against the manifest's k-th entry: swapping two servos' limits fails."""
    env = man["envelope"]
    ids = man["servos"]["ids"]
    k = next(k for k in range(1, len(ids)) if env["eeprom_min"][k] != env["eeprom_min"][0])
    bus = FakeBus(man, set={(ids[k], CT.MIN_POSITION_LIMIT): CT.unsigned(int(env["eeprom_min"][0]), 4)})
    with pytest.raises(client.DeployError, match=rf"^servo {ids[k]}: EEPROM position limits"):
        client.preflight(bus, man)


def test_preflight_reads_negative_limits_as_signed(man):
    m = json.loads(json.dumps(man))
    m["envelope"]["eeprom_min"][0], m["envelope"]["eeprom_max"][0] = -4096, -1
    bus = FakeBus(m)
    i = m["servos"]["ids"][0]
    assert (bus.regs[i][CT.MIN_POSITION_LIMIT], bus.regs[i][CT.MAX_POSITION_LIMIT]) == (2**32 - 4096, 2**32 - 1)
    client.preflight(bus, m)  # both four-byte registers read as signed 32-bit: -4096 .. -1


# --- Bus._check, the SDK's result and error bytes ------------------------------------------------------


def _bus(ids=(1, 2, 3)):
    """A Bus without a port: the SDK's constants and a packet handler that names results."""
    dxl = SimpleNamespace(COMM_SUCCESS=0, COMM_RX_TIMEOUT=-3001, COMM_RX_FAIL=-3002, COMM_RX_CORRUPT=-3003,
                          COMM_TX_FAIL=-1001)
    b = object.__new__(client.Bus)
    b.dxl, b.ids, b.retries, b.reply_ms = dxl, list(ids), 1, 1.0
    b.ph = SimpleNamespace(getTxRxResult=lambda r: f"result {r}", getRxPacketError=lambda e: f"error {e:#x}")
    return b


def test_check_passes_success_without_error():
    _bus()._check("ping", 3, 0, 0)


@pytest.mark.parametrize("result, cause", [(-3003, "CRC error"), (-3001, "timeout: no reply"),
                                           (-3002, "timeout: no reply"), (-1001, "result -1001")])
def test_check_names_the_communication_failure(result, cause):
    with pytest.raises(client.DeployError, match=rf"^{cause} from servo 4 \(ping: result {result}\)$"):
        _bus()._check("ping", 4, result, 0)


def test_check_alert_bit_is_a_hardware_error_and_other_bits_a_refusal():
    with pytest.raises(client.DeployError, match=r"^hardware error on servo 2 \(alert bit, write of address 116\)$"):
        _bus()._check("write of address 116", 2, 0, CT.ALERT_BIT | 0x04)
    with pytest.raises(client.DeployError, match=r"^servo 2 refused write of address 116: error 0x4$"):
        _bus()._check("write of address 116", 2, 0, 0x04)
    with pytest.raises(client.DeployError, match=r"^servo 2 refused ping: error 0x1$"):
        _bus()._check("ping", 2, 0, 0x01)


# --- torque off, the short and the silent servo -------------------------------------------------------


def _torque_bus(torque_after=None, read_fails=(), write_fails=(), drain_fails=False):
    b = _bus()
    b.log = []
    torque_after = torque_after or {}

    def drain():
        if drain_fails:
            raise OSError("port closed")
        b.log.append("drain")

    def write(i, reg, v):
        b.log.append(("w", i, reg, v))
        if i in write_fails:
            raise client.DeployError(f"no reply from {i}")

    def read(i, reg):
        b.log.append(("r", i, reg))
        if i in read_fails:
            raise client.DeployError(f"timeout: no reply from servo {i}")
        return torque_after.get(i, 0)

    b.drain, b.write, b.read = drain, write, read
    return b


def test_torque_off_clears_the_watchdog_then_torque_on_every_servo_and_reads_it_back():
    b = _torque_bus()
    assert b.torque_off() == []
    for i in (1, 2, 3):
        w = [x for x in b.log if x != "drain" and x[1] == i]
        assert w == [("w", i, CT.BUS_WATCHDOG, 0), ("w", i, CT.TORQUE_ENABLE, 0), ("r", i, CT.TORQUE_ENABLE)]
    assert b.log.count("drain") == 3


def test_torque_off_reports_each_failure_and_keeps_going():
    b = _torque_bus(torque_after={2: 1}, read_fails=(3,), write_fails=(1,))
    assert b.torque_off() == ["servo 2: torque still on", "servo 3: timeout: no reply from servo 3"]
    # servo 1's watchdog write failed: its torque write is still tried, and read back
    assert ("w", 1, CT.TORQUE_ENABLE, 0) in b.log and ("r", 1, CT.TORQUE_ENABLE) in b.log


def test_torque_off_stops_at_a_port_that_is_gone():
    assert _torque_bus(drain_fails=True).torque_off() == ["servo 1: port gone (port closed)"]


def test_short_reply_is_the_first_servo_with_a_wrong_length():
    b = _bus((1, 2, 3, 4))
    n = CT.PRESENT_BLOCK[1]
    assert n == 10  # present current (2 bytes) + velocity (4) + position (4), from address 126
    b.reader = SimpleNamespace(data_dict={1: [0] * 10, 2: [0] * 10, 3: [0] * 10, 4: [0] * 10})
    assert b._short_reply() is None
    b.reader.data_dict.update({3: [0] * 9, 4: [0] * 11})
    assert b._short_reply() == 3
    del b.reader.data_dict[3]
    assert b._short_reply() == 3  # no data at all is short too


def test_silent_servo_is_the_first_that_does_not_answer_alone():
    b = _bus((1, 2, 3, 4))
    drained, asked = [], []
    b.drain = lambda: drained.append(1)

    def read4(port, i, a):
        assert port is b.port  # asked on the bus's own port
        asked.append((i, a))
        return 0, (-3001 if i in (3, 4) else 0), 0

    b.port, b.ph = object(), SimpleNamespace(read4ByteTxRx=read4)
    assert b._silent_servo() == 3
    assert asked == [(1, 132), (2, 132), (3, 132)] and len(drained) == 3  # present position, address 132
    b.ph = SimpleNamespace(read4ByteTxRx=lambda port, i, a: (0, 0, 0))
    assert b._silent_servo() == "unknown"


# --- the envelope at its bounds ---------------------------------------------------------------------


def test_goals_on_the_envelope_bounds_pass_and_one_tick_outside_is_refused(man):
    lo = np.asarray(man["envelope"]["goal_min"], float)
    hi = np.asarray(man["envelope"]["goal_max"], float)
    goals = np.vstack([lo, hi, (lo + hi) / 2]).round()
    goals[0], goals[1] = np.ceil(lo), np.floor(hi)
    C.check_envelope(man, goals)
    for j in (0, 4, 8):
        for row, outside in ((0, np.ceil(lo[j]) - 1), (1, np.floor(hi[j]) + 1)):
            g = goals.copy()
            g[row, j] = outside
            with pytest.raises(C.RefusedTarget, match=rf"^command outside the envelope: servo {j + 1} goal "
                               rf"{int(g[row, j])} at step {row} \(allowed {lo[j]:.0f} \.\. {hi[j]:.0f}\)$"):
                C.check_envelope(man, g)


def test_the_first_goal_outside_is_named(man):
    lo = np.asarray(man["envelope"]["goal_min"], float)
    g = np.tile(np.ceil(lo), (5, 1))
    g[3, 2] = lo[2] - 50
    g[4, 0] = lo[0] - 50
    with pytest.raises(C.RefusedTarget, match=r"servo 3 goal .* at step 3 "):
        C.check_envelope(man, g)


# --- the target box -------------------------------------------------------------------------------------


def _features(man, target):
    ws = man["workspace"]
    n = np.asarray(ws["hanging_axis"], float)
    pc, _ = geometry.canonical(np.asarray(target, float).reshape(1, 3), n, ws["phi0_deg"] + ws["delta_str_deg"])
    return geometry.features(pc, n)[0]


def test_a_target_on_the_box_corner_is_accepted_and_just_outside_refused(man):
    target = man["placements"][0]["target_m"]
    g = _features(man, target)
    for side in ("lo", "hi"):
        m = json.loads(json.dumps(man))
        m["target_box"][side] = g.tolist()  # the target's features are the box's corner exactly
        other = "hi" if side == "lo" else "lo"
        m["target_box"][other] = (g + (1.0 if side == "lo" else -1.0)).tolist()
        cmd = C.commands(m, target)
        assert set(cmd) >= {"rho1", "rho2", "rho3", "s3", "tau", "dphi", "bearing"}
        for d in range(3):
            m2 = json.loads(json.dumps(m))
            m2["target_box"][side][d] = float(g[d] + (1e-6 if side == "lo" else -1e-6))
            with pytest.raises(C.RefusedTarget, match=r"outside the workspace"):
                C.commands(m2, target)


def test_a_nan_target_is_outside(man):
    with pytest.raises(C.RefusedTarget, match=r"^target \[nan, .*outside the workspace"):
        C.commands(man, [float("nan"), -0.4, -0.3])


def test_commands_are_inside_the_manifests_ranges(man):
    rng = man["actions"]["ranges"]
    timing = man["actions"]["timing_s"]
    for target in [pl["target_m"] for pl in man["placements"]]:
        cmd = C.commands(man, target)
        assert timing[0] - 1e-9 <= cmd["tau"] <= timing[1] + 1e-9
        assert rng["s3"][0] - 1e-9 <= cmd["s3"] <= rng["s3"][1] + 1e-9
        assert 0.0 <= cmd["bearing"] < 360.0
        p = C.plan(man, target)
        assert p["commands"] == cmd and p["goals"].shape == (len(p["t"]), 9)
        assert not p["goals"].flags.writeable


def test_the_commanded_bearing_is_the_targets_own_turned_by_dphi(man):
    """Eq. 5 turns the target to the canonical bearing phi0 + delta_str; turning the command back
    puts it at the target's own bearing about n, less delta_str, plus the policy's dphi."""
    ws = man["workspace"]
    n = np.asarray(ws["hanging_axis"], float)
    for pl in man["placements"]:
        p = np.asarray(pl["target_m"], float)
        cmd = C.commands(man, p)
        want = (float(BR.bearing_deg(p, n)) - ws["delta_str_deg"] + cmd["dphi"]) % 360.0
        assert (cmd["bearing"] - want + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-6)


def test_the_refusal_names_the_target_its_features_and_the_box(man):
    target = [0.05123, -0.45678, 0.02345]  # more digits than the line keeps
    g = _features(man, target)
    lo, hi = (np.asarray(man["target_box"][k]) for k in ("lo", "hi"))
    assert not np.all((g >= lo) & (g <= hi))
    want = (f"target {np.round(np.asarray(target), 3).tolist()} outside the workspace: (d, e, r) = "
            f"{np.round(g, 3).tolist()} m, allowed {np.round(lo, 3).tolist()} .. {np.round(hi, 3).tolist()}")
    with pytest.raises(C.RefusedTarget) as e:
        C.commands(man, target)
    assert str(e.value) == want


# --- Eq. 5-8 written out, on a manifest where every step changes the numbers --------------------------


def _turned(p, n, deg):
    """p turned about the unit axis n by deg (Rodrigues), written out."""
    a = np.radians(deg)
    return p * np.cos(a) + np.cross(n, p) * np.sin(a) + n * (n @ p) * (1 - np.cos(a))


def _by_hand(man, target):
    """The commands of paper Eq. 5-8 from the manifest's numbers, without embodied_snap.policy.actions
    or commands(): the network (Eq. 6) is the one shared piece."""
    from embodied_snap.policy import networks

    ws, pol, act = man["workspace"], man["policy"], man["actions"]
    n = np.asarray(ws["hanging_axis"], float)
    g = _features(man, target)
    z = (g - np.asarray(pol["norm"]["mu"])) / np.asarray(pol["norm"]["sd"])
    u = networks.outputs(pol["arch"], np.asarray(pol["theta"], float), z[None, :])[0]
    out = {}
    for j, a in enumerate(networks.ACTIONS):  # Eq. 7
        lo, hi = act["ranges"][a]
        f = (min(max(u[j], -1.0), 1.0) + 1.0) / 2.0
        out[a] = lo + (hi - lo) * (f**2 if a == "s3" else f)
    b = ws["phi0_deg"] + out["dphi"]  # Eq. 8: the workspace bin of the commanded canonical bearing
    k = min(max(int(np.floor((b - ws["bin_lo_deg"]) / ws["bin_width_deg"])), 0), len(ws["rho_max"]) - 1)
    for i in range(3):
        out[f"rho{i + 1}"] = min(out[f"rho{i + 1}"], act["workspace_fraction"] * ws["rho_max"][k][i])
    out["tau"] = min(max(out["tau"], act["timing_s"][0]), act["timing_s"][1])
    # turned back from the canonical bearing: the target's own bearing, less delta_str, plus dphi
    out["bearing"] = (float(BR.bearing_deg(np.asarray(target, float), n)) - ws["delta_str_deg"]
                      + out["dphi"]) % 360.0
    return out


def test_commands_are_eq_5_to_8_written_out(man):
    """Targets at 24 bearings about the hanging axis (the features, and so the box, do not depend on
    the bearing), on a manifest whose normalisation is not the identity, whose timing set is the
    middle fifth of the tau range and whose workspace bins differ: every clamp binds somewhere."""
    m = json.loads(json.dumps(man))
    ws, act = m["workspace"], m["actions"]
    lo, hi = act["ranges"]["tau"]
    act["timing_s"] = [lo + 0.4 * (hi - lo), lo + 0.6 * (hi - lo)]
    rng = np.random.default_rng(7)
    ws["rho_max"] = (np.asarray(ws["rho_max"]) * rng.uniform(0.3, 1.0, np.shape(ws["rho_max"]))).tolist()
    m["policy"]["theta"] = rng.normal(0, 1.0, len(m["policy"]["theta"])).tolist()
    assert not np.allclose(m["policy"]["norm"]["mu"], 0) and not np.allclose(m["policy"]["norm"]["sd"], 1)
    n = np.asarray(ws["hanging_axis"], float)
    clipped = dict(tau_lo=0, tau_hi=0, rho=0)
    raw_bearings = []
    for pl in m["placements"]:
        for deg in range(0, 360, 15):
            p = _turned(np.asarray(pl["target_m"], float), n, deg)
            want, got = _by_hand(m, p), C.commands(m, p)
            assert set(got) == set(want)
            for k in want:
                assert got[k] == pytest.approx(want[k], rel=1e-9, abs=1e-9), (k, deg)
            clipped["tau_lo"] += want["tau"] == act["timing_s"][0]
            clipped["tau_hi"] += want["tau"] == act["timing_s"][1]
            clipped["rho"] += any(want[f"rho{i}"] < act["ranges"][f"rho{i}"][1] * 0.999
                                  and want[f"rho{i}"] in [act["workspace_fraction"] * r[i - 1] for r in ws["rho_max"]]
                                  for i in (1, 2, 3))
            raw_bearings.append(float(BR.bearing_deg(p, n)) - ws["delta_str_deg"] + want["dphi"])
    assert min(clipped.values()) > 0, clipped  # each clamp bound at least once
    assert min(raw_bearings) < 0 or max(raw_bearings) >= 360  # the bearing wrapped at least once
