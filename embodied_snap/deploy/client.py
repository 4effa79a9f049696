"""`esnap deploy`: one open-loop trial of the frozen shared policy on the nine servos (paper VI).

The manifest is all it reads (checksum verified). From the target it computes the six commands
(Eq. 5-8) and every goal of the trial before the port is opened; then, over Dynamixel Protocol 2.0
(dynamixel-sdk: PortHandler, PacketHandler 2.0, GroupSyncWrite at Goal Position, GroupSyncRead of
Present Current/Velocity/Position, explicit reads of Hardware Error Status), it checks every servo's
model number, operating mode and EEPROM position limits against the manifest, reads where every
servo rests (refused when one rests where no program leaves it), sets the bus watchdog, enables
torque, brings every servo to the first goal on a slow ramp under a current limit, and plays the
schedule at the manifest's rate, reading every servo back each cycle. Nothing read back changes a
goal (open loop: Table II's "online correction: none"). Torque goes off in a `finally` on success,
any error, a timeout, SIGINT or SIGTERM. Only a complete trial is written, in the rig recording
format (docs/data.md); an aborted one leaves a one-line record under `aborted/`, removed when the
trial of that group id is recorded. Numpy, dynamixel-sdk and the standard library only.

The loop holds its period on a busy PC (docs/deployment.md, "The control loop on a busy PC"): while
the port is open the thread runs at real-time priority (SCHED_FIFO) where the OS permits it, else
at a raised nice value, else as it is (saying so once on stderr); cycles start at absolute deadlines;
the servo log is preallocated and filled in place, with the garbage collector paused, and written
after the trial.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import gc
import json
import os
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np

try:
    from termios import error as _TermiosError  # pyserial's ioctl on a vanished port
except ImportError:  # not a POSIX lab PC
    _TermiosError = OSError

from . import commands as C
from . import controltable as CT
from .manifest import FORMAT as MANIFEST_FORMAT
from .manifest import ManifestError, load


class DeployError(RuntimeError):
    """The trial stopped or was refused: one line naming the cause."""


class ArgumentError(DeployError):
    """A command-line argument the trial cannot use: one line, exit status 2."""


def checked_placement(man: dict, k: int | None) -> int | None:
    """--placement k: one of the manifest's placements, 1-based (0 or -1 would index from the end)."""
    n = len(man["placements"])
    if k is not None and not 1 <= k <= n:
        raise ArgumentError(f"--placement {k}: the manifest has placements 1..{n}")
    return k


def checked_baud(man: dict, b: int | None) -> int:
    """--baud (default: the manifest's): one the XM430 supports and dynamixel-sdk can set."""
    what = f"--baud {b}" if b is not None else f"the manifest's servos.baud {man['servos']['baud']}"
    b = man["servos"]["baud"] if b is None else b
    if b not in CT.BAUD_RATES:
        raise ArgumentError(f"{what}: not a baud rate of the XM430 ({', '.join(map(str, CT.BAUD_RATES))})")
    if b in CT.SDK_CANNOT_SET:
        raise ArgumentError(f"{what}: the XM430 supports it but dynamixel-sdk cannot set it")
    return b


def checked_servo_ids(man: dict) -> list[int]:
    """The manifest's servo ids: 1..9, each once (servo 3(s-1)+k pulls tendon k of section s)."""
    ids = man["servos"]["ids"]
    if sorted(ids) != list(range(1, 10)) or any(isinstance(i, bool) for i in ids):
        raise ArgumentError(f"the manifest's servos.ids {ids}: expected 1..9, each once")
    return ids


def said_by(man: dict) -> str:
    """Whose numbers a refusal quotes: esnap deploy's manifest, or esnap lab's plan."""
    return "the manifest" if man.get("format") == MANIFEST_FORMAT else "the plan"


START_KEYS = ("tolerance_ticks", "ramp_tick_s", "current_ma")


def checked_start(man: dict) -> dict:
    """The manifest's (plan's) servos.start: where the arm may start and how it gets to the first goal."""
    st = man["servos"].get("start")
    if not isinstance(st, dict) or sorted(st) != sorted(START_KEYS):
        raise ArgumentError(f"{said_by(man)} has no servos.start {list(START_KEYS)} (how the arm gets to its first "
                            "goal): written by an older version, write it again")
    return st


PORT_ERRORS = (OSError, _TermiosError)
DRAIN_SHARE = 0.25  # after a lost reply, wait this share of the reply timeout for it to land before
# dropping it (5 ms at the lab's 20 ms): a lost reply and its retry then stay inside the gate's 50 ms
# servo-log gap (cycle 10 + 20 + 5 + the retry), and a reply later still is not taken for the next one


RT_PRIORITY = 40  # SCHED_FIFO priority of the loop: above every normal process, below the kernel's
# interrupt threads (50 on a PREEMPT_RT kernel), which deliver the USB adapter's replies
RAISED_NICE = -10  # without SCHED_FIFO: the scheduler weighs this thread ~10x a normal process
_noticed = False  # the unprivileged notice is said once per process


def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def realtime(priority: int = RT_PRIORITY, nice: int = RAISED_NICE, say=_stderr) -> str:
    """Raise the calling thread (Linux: the policy and the nice value are per thread) for the control
    loop: SCHED_FIFO at `priority` (reset in forked children), else nice `nice`. Returns "fifo",
    "nice" or "normal". Without the permission, or with ESNAP_REALTIME=0 (to measure that case), it
    still runs and says so once per process, in one line naming what to grant (say=None: silently)."""
    global _noticed
    got, why = "normal", "ESNAP_REALTIME=0"
    if os.environ.get("ESNAP_REALTIME") != "0":
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(priority))
            return "fifo"
        except (OSError, AttributeError) as e:  # EPERM: no CAP_SYS_NICE and RLIMIT_RTPRIO too low; not Linux
            why = f"SCHED_FIFO {priority}: {getattr(e, 'strerror', None) or 'not available'}"
        try:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
            got = "nice"
        except (OSError, AttributeError):
            pass
    if say is not None and not _noticed:
        _noticed = True
        say(f"esnap deploy: runs unprivileged ({why}; {'nice ' + str(nice) if got == 'nice' else 'normal priority'}), "
            f"so a busy PC can delay the control loop: allow real-time priority {priority} (ulimit -r {priority}, "
            "an rtprio line in /etc/security/limits.d, or CAP_SYS_NICE; docs/deployment.md)")
    return got


@contextlib.contextmanager
def raised_priority(say=_stderr):
    """The calling thread raised (`realtime`) inside the block, restored after it."""
    tid = threading.get_native_id()
    try:
        policy, param, nice = os.sched_getscheduler(0), os.sched_getparam(0), os.getpriority(os.PRIO_PROCESS, tid)
    except (OSError, AttributeError):  # not Linux: nothing to restore
        policy = None
    try:
        yield realtime(say=say)
    finally:
        if policy is not None:
            with contextlib.suppress(OSError):  # keeps the reset-on-fork flag: clearing it needs CAP_SYS_NICE
                os.sched_setscheduler(0, policy | os.SCHED_RESET_ON_FORK, param)
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, tid, nice)


class Deadlines:
    """Cycle k starts at t0 + k * period on a monotonic clock. Absolute deadlines: a late cycle
    shortens the next wait instead of moving every later cycle (sleeping one period per cycle would
    drift by the cycle's own duration and every oversleep), and a cycle already due starts at once."""

    def __init__(self, period: float, clock=time.monotonic, sleep=time.sleep):
        self.period, self.clock, self.sleep = period, clock, sleep
        self.t0 = clock()

    def wait(self, k: int) -> None:
        delay = self.t0 + k * self.period - self.clock()
        if delay > 0:
            self.sleep(delay)

    def now(self) -> float:
        """Seconds since t0."""
        return self.clock() - self.t0


def _sdk():
    import dynamixel_sdk as dxl

    return dxl


def _port_class(dxl, reply_ms: float):
    class Port(dxl.PortHandler):
        """dynamixel-sdk's port, but a read waits up to 0.5 ms for bytes instead of returning at once:
        the SDK polls the port in a loop until a reply or its timeout, and a non-blocking read makes
        that loop spin a whole core, starving everything else on the lab PC."""

        def setupPort(self, cflag_baud):
            ok = super().setupPort(cflag_baud)
            self.ser.timeout = 0.0005
            return ok

        def setPacketTimeout(self, packet_length):
            # The SDK allows 2 x 16 ms of USB latency timer per reply; with the adapter's latency
            # timer at 1 ms (docs/deployment.md) a reply is late after the manifest's reply_timeout_ms
            # (20 ms), so one lost reply and its retry cost about four 100 Hz cycles, not seven.
            self.packet_start_time = self.getCurrentTime()
            self.packet_timeout = self.tx_time_per_byte * packet_length + reply_ms

    return Port


class Bus:
    """The servo chain behind one serial port, through dynamixel-sdk."""

    def __init__(self, port: str, baud: int, ids, retries: int, reply_ms: float):
        dxl = _sdk()
        self.dxl, self.ids, self.retries, self.reply_ms = dxl, list(ids), retries, reply_ms
        self.baud = baud
        self.port = _port_class(dxl, reply_ms)(port)
        self.ph = dxl.PacketHandler(2.0)
        if not self.port.openPort():
            raise DeployError(f"cannot open port {port}")
        if not self.port.setBaudRate(baud):
            raise DeployError(f"cannot set {baud} baud on {port}")
        a, n = CT.GOAL_POSITION
        self.writer = dxl.GroupSyncWrite(self.port, self.ph, a, n)
        a, n = CT.PRESENT_BLOCK
        self.reader = dxl.GroupSyncRead(self.port, self.ph, a, n)
        for i in self.ids:
            self.reader.addParam(i)
        self.bytes_tx = 0

    def drain(self) -> None:
        """After a lost reply: wait out a reply still in flight, then drop whatever is in the receive
        buffer, so that a late reply is never taken for the answer to the next question."""
        time.sleep(self.reply_ms * DRAIN_SHARE / 1000)
        self.port.is_using = False
        self.port.ser.reset_input_buffer()

    def _check(self, what: str, dxl_id, result: int, error: int = 0) -> None:
        if result != self.dxl.COMM_SUCCESS:
            r = self.ph.getTxRxResult(result)
            cause = ("CRC error" if result == self.dxl.COMM_RX_CORRUPT else
                     "timeout: no reply" if result in (self.dxl.COMM_RX_TIMEOUT, self.dxl.COMM_RX_FAIL) else r)
            raise DeployError(f"{cause} from servo {dxl_id} ({what}: {r})")
        if error & CT.ALERT_BIT:
            raise DeployError(f"hardware error on servo {dxl_id} (alert bit, {what})")
        if error:
            raise DeployError(f"servo {dxl_id} refused {what}: {self.ph.getRxPacketError(error)}")

    def read(self, dxl_id: int, reg) -> int:
        a, n = reg
        fn = {1: self.ph.read1ByteTxRx, 2: self.ph.read2ByteTxRx, 4: self.ph.read4ByteTxRx}[n]
        for _ in range(self.retries + 1):  # a lost or garbled reply is asked again, then it aborts
            try:
                value, result, error = fn(self.port, dxl_id, a)
            except IndexError:  # the SDK unpacked a shorter reply: a late one to another question
                value, result, error = 0, self.dxl.COMM_RX_CORRUPT, 0
            if result == self.dxl.COMM_SUCCESS:
                break
            self.drain()
        self._check(f"read of address {a}", dxl_id, result, error)
        return value

    def write(self, dxl_id: int, reg, value: int) -> None:
        a, n = reg
        fn = {1: self.ph.write1ByteTxRx, 2: self.ph.write2ByteTxRx, 4: self.ph.write4ByteTxRx}[n]
        for _ in range(self.retries + 1):
            result, error = fn(self.port, dxl_id, a, CT.unsigned(value, n))
            if result == self.dxl.COMM_SUCCESS:
                break
            self.drain()
        self._check(f"write of address {a}", dxl_id, result, error)

    def ping(self, dxl_id: int) -> int:
        for _ in range(self.retries + 1):
            model, result, error = self.ph.ping(self.port, dxl_id)
            if result == self.dxl.COMM_SUCCESS:
                break
            self.drain()
        self._check("ping", dxl_id, result, error)
        return model

    def sync_write(self, goals) -> None:
        self.writer.clearParam()
        for i, g in zip(self.ids, goals, strict=True):
            self.writer.addParam(i, CT.unsigned(int(g), 4).to_bytes(4, "little"))
        result = self.writer.txPacket()
        self._check("goal sync write", "all", result)

    def sync_read(self, pos=None, cur=None) -> tuple[np.ndarray, np.ndarray]:
        """Present position (ticks) and current (mA) of every servo, into `pos` and `cur` when given
        (the trial's preallocated log); retried on a lost reply, and on a reply of the wrong length (a
        late reply to an earlier question, which the SDK takes for this one's)."""
        for attempt in range(self.retries + 1):
            result = self.reader.txRxPacket()
            short = self._short_reply() if result == self.dxl.COMM_SUCCESS else None
            if result == self.dxl.COMM_SUCCESS and short is None:
                break
            self.drain()
            if attempt == self.retries:
                if short is not None:
                    raise DeployError(f"garbled reply from servo {short} (present-state sync read: wrong length)")
                self._check("present-state sync read", self._silent_servo(), result)
        pos = np.empty(len(self.ids)) if pos is None else pos
        cur = np.empty(len(self.ids)) if cur is None else cur
        for j, i in enumerate(self.ids):
            pos[j] = CT.signed(self.reader.getData(i, *CT.PRESENT_POSITION), 4)
            cur[j] = CT.signed(self.reader.getData(i, *CT.PRESENT_CURRENT), 2) * CT.CURRENT_UNIT_MA
        return pos, cur

    def _short_reply(self):
        """The first servo whose sync-read data is not PRESENT_BLOCK long, else None."""
        n = CT.PRESENT_BLOCK[1]
        return next((i for i in self.ids if len(self.reader.data_dict.get(i, ())) != n), None)

    def _silent_servo(self):
        """Which servo fails a sync read: ask each on its own, once."""
        for i in self.ids:
            self.drain()
            _, result, _ = self.ph.read4ByteTxRx(self.port, i, CT.PRESENT_POSITION[0])
            if result != self.dxl.COMM_SUCCESS:
                return i
        return "unknown"

    def torque_off(self) -> list[str]:
        """Clear the watchdog and turn torque off on every servo, read back; what failed, one line each.
        Each step is tried on its own: a servo that does not answer may still hear the write."""
        failed = []
        for i in self.ids:
            try:
                self.drain()
            except PORT_ERRORS as e:
                return [f"servo {i}: port gone ({e})"]
            for reg in (CT.BUS_WATCHDOG, CT.TORQUE_ENABLE):
                try:
                    self.write(i, reg, 0)
                except (DeployError, *PORT_ERRORS):
                    pass
            try:
                if self.read(i, CT.TORQUE_ENABLE):
                    failed.append(f"servo {i}: torque still on")
            except (DeployError, *PORT_ERRORS) as e:
                failed.append(f"servo {i}: {e}")
        return failed

    def close(self) -> None:
        try:
            self.port.closePort()
        except PORT_ERRORS:
            pass


def preflight(bus: Bus, man: dict) -> None:
    """Refuse (one line) unless every servo is the manifest's (plan's) model, in its operating mode,
    with its EEPROM position limits and no latched hardware error."""
    sv, env, says = man["servos"], man["envelope"], said_by(man)
    for k, i in enumerate(sv["ids"]):
        try:
            model = bus.ping(i)
        except DeployError as e:
            if k or not str(e).startswith("timeout"):
                raise
            # not even the first servo answers: most likely the bus runs at another baud rate
            raise DeployError(f"{e}; no servo answers at {getattr(bus, 'baud', '?')} baud: check the servos' Baud "
                              f"Rate (address 8) against --baud and {says}'s servos.baud {sv['baud']}") from None
        if model != sv["model_number"]:
            raise DeployError(f"servo {i}: model number {model}, {says} says {sv['model_number']}")
        mode = bus.read(i, CT.OPERATING_MODE)
        if mode != sv["operating_mode"]:
            raise DeployError(f"servo {i}: operating mode {mode}, {says} says {sv['operating_mode']}")
        lo = CT.signed(bus.read(i, CT.MIN_POSITION_LIMIT), 4)
        hi = CT.signed(bus.read(i, CT.MAX_POSITION_LIMIT), 4)
        if (lo, hi) != (env["eeprom_min"][k], env["eeprom_max"][k]):
            raise DeployError(f"servo {i}: EEPROM position limits {lo} .. {hi}, {says} says "
                              f"{env['eeprom_min'][k]} .. {env['eeprom_max'][k]}")
        err = bus.read(i, CT.HARDWARE_ERROR_STATUS)
        if err:
            raise DeployError(f"servo {i}: hardware error status {err:#04x} before the trial")


def start_ramp(bus: Bus, man: dict, first) -> dict:
    """Where the arm starts (docs/deployment.md, "Where the arm starts"), read with torque off: every
    servo's present position. A servo resting farther than servos.start.tolerance_ticks outside its
    EEPROM limits (which hold every goal of every program, so every place a program leaves a servo:
    the gearbox holds a paid-out cable where the program left it) is refused in one line. The others
    get the ramp to the first goal `first`: straight lines at no more than servos.start.ramp_tick_s,
    all servos arriving together; none when every servo is within one ramp step of it. Returns the
    record written to meta.json as `start`, with the ramp's goals (n, 9), frozen, under "goals"."""
    sv, env, st = man["servos"], man["envelope"], man["servos"]["start"]
    pos = np.array([CT.signed(bus.read(i, CT.PRESENT_POSITION), 4) for i in sv["ids"]], np.int64)
    tol = st["tolerance_ticks"]
    lo, hi = np.asarray(env["eeprom_min"]), np.asarray(env["eeprom_max"])
    beyond = np.maximum(lo - pos, pos - hi)
    if (beyond > tol).any():
        j = int(np.argmax(beyond > tol))
        i = sv["ids"][j]
        raise DeployError(f"servo {i}: rests at {pos[j]} ticks, {beyond[j]} outside its EEPROM limits {lo[j]} .. "
                          f"{hi[j]} (tolerance {tol}), where no program of {said_by(man)} leaves it: is its Homing "
                          f"Offset set (the straight hanging arm reads 0), is the right servo on id {i}?")
    first = np.asarray(first, np.int64)
    step = st["ramp_tick_s"] / float(sv["hz"])
    n = int(np.ceil(np.abs(first - pos).max() / step - 1e-9))
    goals = np.rint(pos + (first - pos) * (np.arange(1, n + 1) / n)[:, None]).astype(np.int64) if n > 1 else \
        np.empty((0, len(pos)), np.int64)
    goals.setflags(write=False)
    return dict(present=pos.tolist(), first_goal=first.tolist(), ramp_cycles=len(goals), ramp_tick_s=st["ramp_tick_s"],
                current_limit_ma=st["current_ma"], goals=goals)


def ramped(start: dict) -> str:
    """What the start ramp did, for the operator (esnap deploy's and esnap lab acquire's line)."""
    far = int(np.abs(np.subtract(start["present"], start["first_goal"])).max())
    return (f"every servo brought to the first goal from where it rested (up to {far} ticks away) in "
            f"{start['ramp_cycles']} cycles at {start['ramp_tick_s']:g} tick/s")


def _sigterm(signum, frame):
    raise DeployError("terminated (SIGTERM)")


# execute() writes each row's goal in that row's cycle, before its sync-read (rawformat.GOAL_TIMING)
LOG_GOAL_TIMING = "row"


def _hardware_error(bus: Bus, ids, k: int, where: str) -> None:
    """Cycle k's Hardware Error Status read: one servo per cycle, round robin."""
    i = ids[k % len(ids)]
    err = bus.read(i, CT.HARDWARE_ERROR_STATUS)
    if err:  # latched on the servo: asked again after a drain, so a stray late reply cannot stop a trial
        bus.drain()
        err = bus.read(i, CT.HARDWARE_ERROR_STATUS)
    if err:
        raise DeployError(f"hardware error on servo {i}: status {err:#04x} {where}")


def ramp(bus: Bus, man: dict, start: dict) -> None:
    """Play the start ramp (`start_ramp`; torque on) at the bus rate, aborting when a servo's present
    current passes the limit: a cable that pulls against the arm on the way to the first goal (the
    ramp runs to the straight hanging arm, which no taut cable resists). Adds each servo's peak
    current on the ramp to `start` (peak_current_ma)."""
    ids, goals, lim = man["servos"]["ids"], start["goals"], start["current_limit_ma"]
    pos, cur, peak = np.empty(len(ids)), np.empty(len(ids)), np.zeros(len(ids))
    clock = Deadlines(1.0 / float(man["servos"]["hz"]))
    try:
        for k in range(len(goals)):
            clock.wait(k)
            bus.sync_write(goals[k])
            bus.sync_read(pos, cur)
            np.maximum(peak, np.abs(cur), out=peak)
            if (np.abs(cur) > lim).any():
                j = int(np.argmax(np.abs(cur) > lim))
                raise DeployError(f"servo {ids[j]}: {abs(cur[j]):.0f} mA on the start ramp at {pos[j]:.0f} ticks, "
                                  f"on its way from {start['present'][j]} to {goals[-1][j]} (limit {lim:g} mA): its "
                                  "cable pulls against the arm; is its Homing Offset set, its cable routed as the goal "
                                  "map says?")
            _hardware_error(bus, ids, k, f"on the start ramp, at {clock.now():.2f} s")
    finally:
        start["peak_current_ma"] = np.round(peak, 1).tolist()


def execute(bus: Bus, man: dict, goals: np.ndarray, on_cycle=None, start: dict | None = None) -> np.ndarray:
    """Play the schedule open loop; returns the servo log (T, 1 + 27): t, then goal, present,
    current per servo. Every goal is in `goals` before this is called, and nothing here writes it.
    With torque on, the start ramp (`start`, from `start_ramp`) runs first; the log holds the
    schedule alone, its clock starting at the schedule's first cycle. The log is allocated before
    the first cycle and filled in place; `on_cycle(k, t)`, if given, runs inside the cycle and must
    not block."""
    assert not goals.flags.writeable, "the schedule must be frozen before the first byte moves the arm"
    ids = man["servos"]["ids"]
    period = 1.0 / float(man["servos"]["hz"])
    wd = int(round(man["servos"]["watchdog_ms"] / CT.WATCHDOG_UNIT_MS))
    for i in ids:
        bus.write(i, CT.BUS_WATCHDOG, wd)
    for i in ids:
        bus.write(i, CT.TORQUE_ENABLE, 1)
    if start is not None:
        assert not start["goals"].flags.writeable and np.array_equal(start["first_goal"], goals[0])
        ramp(bus, man, start)
    log = np.empty((len(goals), 1 + 27))
    per_servo = log[:, 1:].reshape(len(goals), 9, 3)  # a view: goal, present, current of each servo
    per_servo[:, :, 0] = goals
    gc_on = gc.isenabled()
    gc.disable()  # a collection costs milliseconds at a random cycle; the trial allocates little
    try:
        clock = Deadlines(period)
        for k in range(len(goals)):
            clock.wait(k)
            bus.sync_write(goals[k])
            bus.sync_read(per_servo[k, :, 1], per_servo[k, :, 2])
            t = log[k, 0] = clock.now()
            _hardware_error(bus, ids, k, f"at t = {t:.2f} s")
            if on_cycle:
                on_cycle(k, t)
    finally:
        if gc_on:
            gc.enable()
    return log


def write_trial(out: Path, meta: dict, log: np.ndarray) -> list[Path]:
    """The servo log and meta.json in the rig format (rawformat; needs pandas and pyarrow, else the
    log is kept as servo.npz for conversion on another machine). A recorded group is no longer
    aborted: its `aborted/<group_id>.json`, left by an earlier try, goes."""
    d = Path(out) / "groups" / meta["group_id"]
    d.mkdir(parents=True, exist_ok=True)
    try:
        import pandas as pd

        from .. import rawformat as RF
        from ..io import write_parquet
    except ImportError:
        np.savez(d / "servo.npz", log=log)
        files = [d / "servo.npz"]
    else:
        df = pd.DataFrame(log, columns=RF.servo_columns())
        for c in df.columns[1:]:
            if not c.startswith("current"):
                df[c] = df[c].round().astype("int64")
        write_parquet(df, d / "servo.parquet")
        files = [d / "servo.parquet"]
    write_meta(d / "meta.json", meta)
    (Path(out) / "aborted" / f"{meta['group_id']}.json").unlink(missing_ok=True)
    return files + [d / "meta.json"]


def write_meta(path: Path, meta: dict) -> None:
    with open(path, "w") as f:
        json.dump(meta, f, indent=1, sort_keys=True)
        f.write("\n")


def drive(man: dict, port: str, baud: int, goals: np.ndarray, on_cycle=None, started: dict | None = None) -> tuple:
    """Open the port, preflight, read where the arm rests, ramp to the first goal, play the frozen
    `goals`, and turn torque off whatever happened: (servo log or None, cause of an abort or None,
    servos whose torque-off failed). `man` needs the manifest's `servos` and `envelope` sections
    (esnap deploy's manifest, esnap lab's plan); every argument was checked before this is called.
    `started`, if given, receives the start's record (`start_ramp`, for meta.json's `start`)."""
    bus = Bus(port, baud, man["servos"]["ids"], man["servos"]["reply_retries"],
              man["servos"]["reply_timeout_ms"])
    old = signal.signal(signal.SIGTERM, _sigterm)
    # Ctrl-C stops the arm even when the parent ignores SIGINT (a shell's background job starts
    # with it ignored, and Python then installs no handler of its own)
    old_int = signal.signal(signal.SIGINT, signal.default_int_handler)
    cause, log, start = None, None, None
    with raised_priority():  # the whole time the arm may move, torque off included
        try:
            preflight(bus, man)
            start = start_ramp(bus, man, goals[0])
            log = execute(bus, man, goals, on_cycle, start)
        except DeployError as e:
            cause = str(e)
        except KeyboardInterrupt:
            cause = "interrupted (SIGINT)"
        except PORT_ERRORS as e:
            cause = f"port closed or lost: {e}"
        finally:
            failed = bus.torque_off()
            bus.close()
            if started is not None and start is not None:
                started.update({k: v for k, v in start.items() if k != "goals"})
            signal.signal(signal.SIGTERM, old)
            signal.signal(signal.SIGINT, old_int)
    return log, cause, failed


def write_aborted(out: Path, group_id: str, cause: str, failed: list[str], **extra) -> Path:
    """`aborted/<group_id>.json`: why the trial stopped and whether torque went off."""
    a = Path(out) / "aborted"
    a.mkdir(parents=True, exist_ok=True)
    with open(a / f"{group_id}.json", "w") as f:
        json.dump(dict(group_id=group_id, cause=cause, torque_off_failed=failed, **extra), f, indent=1)
    return a / f"{group_id}.json"


def aborted_line(cause: str, failed: list[str]) -> str:
    more = f"; torque off failed: {failed[0]}" if failed else "; torque off on all servos"
    return f"aborted: {cause}{more}"


def run(manifest, port: str | None, target, *, baud: int | None = None, out=None, group_id: str = "dep_0001",
        placement: int | None = None, dry_run: bool = False, confirm=None, say=print) -> dict:
    """One trial. Returns {commands, phases, goals, log, cause, torque_off, start}; raises DeployError
    (one line) when it refuses or aborts, after torque went off. `placement`: which of the manifest's
    placements the block stands at (recorded in the program; Table II counts placements)."""
    try:
        man = load(manifest)
        trial = C.plan(man, target)
    except (ManifestError, C.RefusedTarget) as e:
        raise DeployError(f"refused: {e}") from None
    # The one door to the port (esnap deploy and the simulated rig's trials): what the command
    # line checked is checked again here, before the port opens.
    checked_servo_ids(man)
    checked_start(man)
    checked_placement(man, placement)
    baud = checked_baud(man, baud)
    cmd, goals = trial["commands"], trial["goals"]
    say("commands: " + ", ".join(f"{k} {v:.3f}" for k, v in cmd.items()))
    say(f"schedule: {len(goals)} goals at {man['servos']['hz']} Hz over {trial['t'][-1]:.2f} s; phases "
        + ", ".join(f"{k} {v:.2f}" for k, v in trial["phases"].items()))
    if dry_run:
        for k in range(0, len(goals), max(1, int(man["servos"]["hz"]) // 10)):
            say(f"{trial['t'][k]:6.2f} " + " ".join(f"{g:6d}" for g in goals[k]))
        return dict(trial, log=None, cause=None)
    if confirm is not None and not confirm():
        raise DeployError("refused: not confirmed by the operator")
    out_dir = Path(out) if out else None
    started = {}
    log, cause, failed = drive(man, port, baud, goals, started=started)
    if started.get("ramp_cycles"):
        say(f"start: {ramped(started)}")
    result = dict(trial, log=log, cause=cause, torque_off=not failed, start=started)
    if cause is not None:
        if out_dir is not None:
            write_aborted(out_dir, group_id, cause, failed, manifest_sha256=man["checksum"])
        raise DeployError(aborted_line(cause, failed))
    if out_dir is not None:
        meta = dict(format_version=1, group_id=group_id, evidence_set="deployment", category="placement",
                    session="lab", recorded_at=_dt.datetime.now().isoformat(timespec="seconds"), source="rig",
                    goal_timing=LOG_GOAL_TIMING, base=dict(pos=[0.0, 0.0, 0.0], quat=[1.0, 0.0, 0.0, 0.0]),
                    axis=man["workspace"]["hanging_axis"], manifest_sha256=man["checksum"],
                    program=dict(kind="primitive", **{k: round(v, 4) for k, v in cmd.items()},
                                 target_m=[float(x) for x in np.ravel(target)]),
                    labels={k: v for k, v in trial["phases"].items() if k != "t_end"}, start=started)
        if placement is not None:
            meta["program"]["placement"] = int(placement)
        write_trial(out_dir, meta, log)
    return result
