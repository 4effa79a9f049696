"""The deployment control loop on a busy PC (docs/deployment.md, "The control loop on a busy PC"):
absolute cycle deadlines, the servo log filled in place, and the priority step with its once-only
notice when the OS does not permit it. A fake clock and fake scheduler calls: no timing thresholds
(bench/loop_load.py measures the real loop under load)."""

from __future__ import annotations

import errno
import gc
import os

import numpy as np
import pytest

from embodied_snap.deploy import client


class FakeClock:
    """time.monotonic / time.sleep stand-ins: every sleep oversleeps by `late` s."""

    def __init__(self, late=0.0):
        self.t, self.late, self.slept = 100.0, late, []

    def __call__(self):
        return self.t

    def sleep(self, s):
        self.slept.append(s)
        self.t += s + self.late


def test_deadlines_are_absolute_and_do_not_drift():
    clk = FakeClock(late=0.0007)
    d = client.Deadlines(0.01, clk, clk.sleep)
    starts = []
    for k in range(200):
        d.wait(k)
        starts.append(d.now())
        clk.t += 0.004  # the cycle's own work
    # every cycle after the first (due at once) starts one oversleep after its own deadline: neither
    # the work nor the oversleeps add up
    assert starts[0] == 0.0 and np.allclose(np.array(starts[1:]) - 0.01 * np.arange(1, 200), 0.0007)


def test_a_late_cycle_is_caught_up_not_shifted():
    clk = FakeClock()
    d = client.Deadlines(0.01, clk, clk.sleep)
    starts = []
    for k in range(10):
        d.wait(k)
        starts.append(round(d.now(), 6))
        clk.t += 0.035 if k == 2 else 0.002  # cycle 2 stalls (the machine was busy)
    # cycles 3-6 were already due: they start at once, back to back; cycle 7 is on its deadline again
    assert starts == [0.0, 0.01, 0.02, 0.055, 0.057, 0.059, 0.061, 0.07, 0.08, 0.09]


class FakeBus:
    """What execute asks of the bus, recorded; present = goal + 1, current = 2."""

    def __init__(self, clock, fail_at=None):
        self.clock, self.fail_at = clock, fail_at
        self.writes, self.reads, self.gc_during = [], [], []

    def write(self, i, reg, value):
        pass

    def sync_write(self, goals):
        self.writes.append((self.clock(), np.array(goals)))
        self.gc_during.append(gc.isenabled())
        if self.fail_at is not None and len(self.writes) > self.fail_at:
            raise client.DeployError("timeout: no reply from servo 5")
        self.clock.t += 0.003

    def sync_read(self, pos, cur):
        self.reads.append((pos, cur))
        pos[:] = self.writes[-1][1] + 1
        cur[:] = 2.0
        return pos, cur

    def read(self, i, reg):
        return 0


def _man():
    return dict(servos=dict(ids=list(range(1, 10)), hz=100, watchdog_ms=100))


def test_execute_keeps_deadlines_and_fills_the_log_in_place(monkeypatch):
    clk = FakeClock(late=0.0004)
    monkeypatch.setattr(client, "Deadlines", lambda period: _fake_deadlines(period, clk))
    goals = np.arange(30 * 9).reshape(30, 9)
    goals.flags.writeable = False
    bus = FakeBus(clk)
    log = client.execute(bus, _man(), goals)
    t0 = clk.t0
    starts = np.array([t for t, _ in bus.writes]) - t0
    assert np.allclose(starts[1:] - 0.01 * np.arange(1, 30), 0.0004)  # absolute deadlines, no drift
    assert np.array_equal(log[:, 1:].reshape(30, 9, 3)[:, :, 0], goals)
    assert np.array_equal(log[:, 1:].reshape(30, 9, 3)[:, :, 1], goals + 1)
    assert all(np.shares_memory(p, log) and np.shares_memory(c, log) for p, c in bus.reads)  # no per-cycle arrays
    assert not any(bus.gc_during) and gc.isenabled()  # collector paused inside the cycles only


def test_execute_restores_the_collector_when_a_cycle_fails(monkeypatch):
    clk = FakeClock()
    monkeypatch.setattr(client, "Deadlines", lambda period: _fake_deadlines(period, clk))
    goals = np.zeros((20, 9), int)
    goals.flags.writeable = False
    with pytest.raises(client.DeployError, match="no reply from servo 5"):
        client.execute(FakeBus(clk, fail_at=5), _man(), goals)
    assert gc.isenabled()


REAL_DEADLINES = client.Deadlines


def _fake_deadlines(period, clk):
    d = REAL_DEADLINES(period, clk, clk.sleep)
    clk.t0 = d.t0
    return d


# --- the priority step ---------------------------------------------------------------------------------


@pytest.fixture
def sched(monkeypatch):
    """Fake scheduler calls: `allow` says which succeed; every call is recorded."""
    calls = dict(fifo=[], nice=[], allow={"fifo", "nice"})

    def setscheduler(pid, policy, param):
        calls["fifo"].append((pid, policy, param.sched_priority))
        if policy & ~os.SCHED_RESET_ON_FORK == os.SCHED_FIFO and "fifo" not in calls["allow"]:
            raise PermissionError(errno.EPERM, "Operation not permitted")

    def setpriority(which, who, prio):
        calls["nice"].append(prio)
        if prio < 0 and "nice" not in calls["allow"]:
            raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(os, "sched_setscheduler", setscheduler)
    monkeypatch.setattr(os, "setpriority", setpriority)
    monkeypatch.setattr(os, "sched_getscheduler", lambda pid: os.SCHED_OTHER)
    monkeypatch.setattr(os, "sched_getparam", lambda pid: os.sched_param(0))
    monkeypatch.setattr(os, "getpriority", lambda which, who: 0)
    monkeypatch.setattr(client, "_noticed", False)
    monkeypatch.delenv("ESNAP_REALTIME", raising=False)
    return calls


def test_privileged_runs_fifo_without_a_notice_and_restores(sched, capsys):
    with client.raised_priority() as got:
        assert got == "fifo"
    assert sched["fifo"][0] == (0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, client.RT_PRIORITY)
    assert sched["fifo"][-1][1] & ~os.SCHED_RESET_ON_FORK == os.SCHED_OTHER  # back to what it was
    assert capsys.readouterr().err == ""


def test_unprivileged_says_so_once_on_stderr(sched, capsys):
    sched["allow"] = set()
    for _ in range(3):
        with client.raised_priority() as got:
            assert got == "normal"
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1  # once per process, one line
    assert "unprivileged" in err[0] and "Operation not permitted" in err[0]
    assert f"ulimit -r {client.RT_PRIORITY}" in err[0] and "limits.d" in err[0] and "CAP_SYS_NICE" in err[0]


def test_without_fifo_the_loop_still_gets_a_raised_nice(sched, capsys):
    sched["allow"] = {"nice"}
    with pytest.raises(client.DeployError):
        with client.raised_priority() as got:
            assert got == "nice"
            raise client.DeployError("aborted")  # the priority is restored on every exit
    assert sched["nice"] == [client.RAISED_NICE, 0]
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and f"nice {client.RAISED_NICE}" in err[0]


def test_the_priority_step_can_be_switched_off(sched, monkeypatch, capsys):
    monkeypatch.setenv("ESNAP_REALTIME", "0")
    assert client.realtime() == "normal" and client.realtime() == "normal"
    assert sched["fifo"] == [] and sched["nice"] == []
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "ESNAP_REALTIME=0" in err[0]


def test_the_twin_servos_ask_quietly(sched, capsys):
    """The virtual bus's threads stand for the servos' own MCUs: no notice of theirs, and they do not
    use up the client's."""
    sched["allow"] = set()
    assert client.realtime(client.RT_PRIORITY + 1, say=None) == "normal"
    assert capsys.readouterr().err == "" and not client._noticed


def test_a_late_reply_of_the_wrong_length_is_asked_again():
    """Under load a reply can land after its question was given up: the next sync read must not take
    a 1-byte Hardware Error Status reply for a servo's present state (the SDK would crash on it)."""
    dxl = client._sdk()
    block = (1234).to_bytes(10, "little")  # present current 1234 * 2.69 mA, position 0

    class Reader:
        def __init__(self, answers):
            self.answers, self.data_dict = answers, {}

        def txRxPacket(self):
            self.data_dict = self.answers.pop(0)
            return dxl.COMM_SUCCESS

        def getData(self, i, a, n):
            return int.from_bytes(self.data_dict[i][a - 126:a - 126 + n], "little")

    bus = client.Bus.__new__(client.Bus)
    bus.dxl, bus.ids, bus.retries, bus.reply_ms = dxl, [1, 2], 3, 20.0
    drains = []
    bus.drain = lambda: drains.append(1)
    bus.reader = Reader([{1: bytearray(1), 2: bytearray(block)}, {1: bytearray(block), 2: bytearray(block)}])
    pos, cur = bus.sync_read()
    assert len(drains) == 1 and np.allclose(cur, 1234 * 2.69) and np.all(pos == 0)
    bus.reader = Reader([{1: bytearray(block), 2: bytearray(3)}] * 4)
    with pytest.raises(client.DeployError, match="garbled reply from servo 2"):
        bus.sync_read()
