"""A virtual Dynamixel Protocol 2.0 bus on a pseudo-terminal: nine XM430-W350 servos whose shafts
are the simulated rig's (stepper.py).

`VirtualBus(stepper).start()` opens a pty and answers on it, in a thread, like the real chain
behind a U2D2 (the arm's physics runs in a second thread, `_physics`, so a reply never waits for it):
CRC-16 (polynomial 0x8005), byte stuffing, PING, READ, WRITE, SYNC_READ, SYNC_WRITE
(broadcast id 0xFE). Goals written drive the stepper in wall-clock time from the first goal
written with torque on (the trial clock); present position and current are the stepper's. Torque
Enable (64), the Bus Watchdog (98: a servo that hears no instruction packet for its period stops
where it is and refuses goals until 98 is cleared), EEPROM locking (operating mode and position
limits are writable only with torque off), Hardware Error Status (70, with the alert bit in every
status packet) behave as on the servo. Every goal received is logged (`goal_log`).

The two threads are the servos' own microcontrollers, so they get the client's priority treatment
(`client.realtime`, quietly: the client says once if it runs unprivileged): the bus thread runs
just above the client's loop, the physics below it (it yields every slice, so it takes a small
share of a core), which also keeps the physics from being preempted while it holds the GIL the
bus thread waits for. Without the permission the physics runs niced instead.

`rest` (optional, ticks per servo, default 0): what each servo reads while its shaft rests where
the simulated arm hangs straight, as a servo whose Homing Offset is not set, or one another
program left elsewhere; goals are read in the same frame (a goal of `rest` holds the shaft).

Faults (`faults`, all optional): no_reply {id, at_s}; bad_crc {at_s}; hw_error {id, at_s, bits};
model {id, number}; eeprom {id}; close {at_s}. Times are on the trial clock.
"""

from __future__ import annotations

import os
import select
import threading
import time
import tty

import numpy as np

from ..deploy import controltable as CT
from ..deploy.client import RT_PRIORITY, realtime

HEADER = b"\xff\xff\xfd\x00"
BROADCAST = 0xFE
PING, READ, WRITE, STATUS, SYNC_READ, SYNC_WRITE = 0x01, 0x02, 0x03, 0x55, 0x82, 0x83
ERR_ACCESS, ERR_CRC = 0x07, 0x03
PHYSICS_SLICE_S = 0.002  # trial clock: the physics thread checks the watchdog and yields this often
PHYSICS_YIELD_S = 0.0005  # wall clock: how long it yields each time
PHYSICS_NICE = 5  # without real-time priority: the physics thread's nice increment (Linux: per thread)
BUS_PRIORITY = RT_PRIORITY + 1  # SCHED_FIFO: a servo answers as soon as the client's packet is in
PHYSICS_PRIORITY = RT_PRIORITY - 10  # below the client's loop and the bus thread


def _crc_table():
    t = []
    for i in range(256):
        c = i << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x8005) if c & 0x8000 else (c << 1)
        t.append(c & 0xFFFF)
    return t


_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    """Dynamixel Protocol 2.0 CRC-16 (CRC-16/BUYPASS: poly 0x8005, init 0, not reflected)."""
    c = 0
    for b in data:
        c = ((c << 8) ^ _TABLE[((c >> 8) ^ b) & 0xFF]) & 0xFFFF
    return c


def stuff(body: bytes) -> bytes:
    """Byte stuffing: FF FF FD inside a packet's instruction and parameters gets an extra FD."""
    return body.replace(b"\xff\xff\xfd", b"\xff\xff\xfd\xfd")


def unstuff(body: bytes) -> bytes:
    return body.replace(b"\xff\xff\xfd\xfd", b"\xff\xff\xfd")


def packet(dxl_id: int, inst: int, params: bytes) -> bytes:
    body = stuff(bytes([inst]) + params)
    p = HEADER + bytes([dxl_id]) + (len(body) + 2).to_bytes(2, "little") + body
    return p + crc16(p).to_bytes(2, "little")


def parse(buf: bytearray) -> tuple[list[tuple[int, int, bytes, bool]], bytearray]:
    """Complete packets in buf: [(id, instruction, params, crc_ok)], and what is left."""
    out = []
    while True:
        k = buf.find(HEADER)
        if k < 0:
            return out, buf[-3:] if len(buf) > 3 else buf
        buf = buf[k:]
        if len(buf) < 7:
            return out, buf
        n = 7 + int.from_bytes(buf[5:7], "little")
        if len(buf) < n:
            return out, buf
        p, buf = bytes(buf[:n]), buf[n:]
        ok = crc16(p[:-2]) == int.from_bytes(p[-2:], "little")
        body = unstuff(p[7:-2])
        out.append((p[4], body[0] if body else -1, body[1:], ok))


class Servo:
    """One XM430's control table (bytes) over a shaft of the stepper."""

    def __init__(self, i: int, model: int, lim_min: int, lim_max: int):
        self.i = i
        self.mem = bytearray(256)
        self.put(CT.MODEL_NUMBER, model)
        self.put((6, 1), 46)  # firmware version
        self.put((7, 1), i + 1)  # id
        self.put(CT.OPERATING_MODE, CT.EXTENDED_POSITION_MODE)
        self.put(CT.MAX_POSITION_LIMIT, CT.unsigned(lim_max, 4))
        self.put(CT.MIN_POSITION_LIMIT, CT.unsigned(lim_min, 4))
        self.hw_error = 0
        self.watchdog_fired = False

    def put(self, reg, value: int) -> None:
        a, n = reg
        self.mem[a:a + n] = int(value).to_bytes(n, "little")

    def get(self, reg) -> int:
        a, n = reg
        return int.from_bytes(self.mem[a:a + n], "little")

    @property
    def torque(self) -> bool:
        return bool(self.mem[CT.TORQUE_ENABLE[0]])


class VirtualBus:
    def __init__(self, stepper, eeprom_min, eeprom_max, faults: dict | None = None, model: int = CT.XM430_W350,
                 rest=None):
        self.stepper = stepper
        self.rest = np.zeros(9) if rest is None else np.broadcast_to(np.asarray(rest, float), (9,)).copy()
        self.faults = dict(faults or {})
        self.servos = [Servo(i, model, int(eeprom_min[i]), int(eeprom_max[i])) for i in range(9)]
        f = self.faults
        if "model" in f:
            self.servos[f["model"]["id"] - 1].put(CT.MODEL_NUMBER, f["model"]["number"])
        if "eeprom" in f:
            s = self.servos[f["eeprom"]["id"] - 1]
            s.put(CT.MAX_POSITION_LIMIT, CT.unsigned(CT.signed(s.get(CT.MAX_POSITION_LIMIT), 4) + 100, 4))
        self.goal_log: list[tuple[float, int, int, bool]] = []  # (trial time s, id, goal, applied)
        self.t0: float | None = None  # wall time of the first goal written with torque on
        self.first_goal_t: float | None = None  # ... on the trial clock (where a program's time starts)
        self.last_rx = time.monotonic()
        self.last_rx_t = 0.0  # trial clock of the last instruction packet
        self.tx_bytes = self.rx_bytes = 0
        self.closed = False
        self.stopped_at: dict[int, float] = {}  # id -> trial time its watchdog stopped it
        self._stop = threading.Event()
        self._lock = threading.Lock()

    # --- the pty ---------------------------------------------------------------------------------
    def start(self) -> str:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        tty.setraw(self.master)
        self.port = os.ttyname(self.slave)
        self.thread = threading.Thread(target=self._serve, name="vbus", daemon=True)
        self.sim_thread = threading.Thread(target=self._physics, name="vbus-physics", daemon=True)
        self.thread.start()
        self.sim_thread.start()
        return self.port

    def stop(self) -> None:
        self._stop.set()
        self.thread.join(5)
        self.sim_thread.join(5)
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.stop()

    def now(self) -> float:
        """Trial clock (s); 0 before the first goal."""
        return 0.0 if self.t0 is None else time.monotonic() - self.t0

    def _serve(self) -> None:
        """Answer every packet as it arrives. The arm's physics runs in its own thread (`_physics`),
        so a reply never waits for the simulation to catch up."""
        realtime(BUS_PRIORITY, say=None)
        buf = bytearray()
        while not self._stop.is_set():
            if self.closed:
                time.sleep(0.002)
                continue
            r, _, _ = select.select([self.master], [], [], 0.002)
            if r:
                try:
                    data = os.read(self.master, 4096)
                except OSError:
                    data = b""
                self.rx_bytes += len(data)
                buf += data
                pkts, buf = parse(buf)
                for p in pkts:
                    with self._lock:
                        self.last_rx = time.monotonic()
                        self.last_rx_t = self.now()
                        self._handle(*p)

    def _physics(self) -> None:
        """Step the arm to the trial clock, in slices of PHYSICS_SLICE_S (the watchdog and the faults
        checked before each), and wait for the clock once it is caught up. On Linux a thread has its own
        scheduling: this one runs below the bus thread, so a busy machine delays the physics first."""
        if realtime(PHYSICS_PRIORITY, nice=0, say=None) != "fifo":
            try:
                os.nice(PHYSICS_NICE)
            except OSError:
                pass
        while not self._stop.is_set():
            with self._lock:
                t = self._tick()
            if t is None or t <= self.stepper.t + self.stepper.dt:
                time.sleep(0.001)
                continue
            self.stepper.advance(min(t, self.stepper.t + PHYSICS_SLICE_S))
            # yield to the bus thread: a slice costs ~0.15 ms, so this still runs 3x faster than
            # real time, and a loaded machine delays the physics, never a reply
            time.sleep(PHYSICS_YIELD_S)

    def _tick(self) -> float | None:
        """The watchdog and the faults that start at a time, up to now; returns now (None before
        the first goal)."""
        if self.t0 is None:
            return None
        t = self.now()
        if not self.closed and select.select([self.master], [], [], 0)[0]:
            return t  # a packet has arrived and the bus thread has yet to read it: the servos heard it
        quiet_from = self.last_rx - self.t0
        for s in self.servos:
            # the watchdog fires exactly one period after the last instruction packet: the shafts
            # move up to that instant and not after, however late this thread looks
            wd = s.get(CT.BUS_WATCHDOG)
            deadline = quiet_from + wd * CT.WATCHDOG_UNIT_MS / 1000
            if 0 < wd < 0xFF and s.torque and t > deadline:
                s.put(CT.BUS_WATCHDOG, 0xFF)
                s.watchdog_fired = True
                self.stepper.stop(s.i, deadline)
                self.stopped_at[s.i + 1] = deadline
        f = self.faults
        if "hw_error" in f and t >= f["hw_error"]["at_s"]:
            s = self.servos[f["hw_error"]["id"] - 1]
            if not s.hw_error:
                s.hw_error = f["hw_error"].get("bits", 0x20)  # overload
                s.put(CT.TORQUE_ENABLE, 0)  # the servo shuts its torque off on a hardware error
                self.stepper.set_torque(s.i, False, t)
        if "close" in f and t >= f["close"]["at_s"] and not self.closed:
            self.closed = True
            os.close(self.master)  # the adapter is gone: the client's next read or write fails
        return t

    # --- instructions ----------------------------------------------------------------------------
    def _silent(self, dxl_id: int) -> bool:
        f = self.faults.get("no_reply")
        return bool(f and f["id"] == dxl_id and self.now() >= f.get("at_s", 0.0) and
                    (self.t0 is not None or f.get("at_s", 0.0) == 0.0))

    def _reply(self, dxl_id: int, err: int, data: bytes = b"") -> None:
        if self._silent(dxl_id) or self.closed:
            return
        s = self.servos[dxl_id - 1]
        if s.hw_error:
            err |= CT.ALERT_BIT
        p = packet(dxl_id, STATUS, bytes([err]) + data)
        f = self.faults.get("bad_crc")
        if f and self.t0 is not None and self.now() >= f["at_s"]:
            p = p[:-1] + bytes([p[-1] ^ 0x5A])
        try:
            os.write(self.master, p)
            self.tx_bytes += len(p)
        except OSError:
            pass

    def _refresh(self, s: Servo, a: int, n: int) -> None:
        """The present state, for a read of n bytes from address a. A read of the position alone (the
        client's, of where the arm rests) draws no current noise from the rig's stream, so the
        stream, and every recording of the rig, is as it was without that read."""
        pos = self.stepper.present()[s.i] + self.rest[s.i]
        s.put(CT.PRESENT_POSITION, CT.unsigned(int(round(pos)), 4))
        if (a, n) != CT.PRESENT_POSITION:
            cur = self.stepper.current_ma()[s.i] / CT.CURRENT_UNIT_MA
            s.put(CT.PRESENT_CURRENT, CT.unsigned(int(round(cur)), 2))
        s.put(CT.HARDWARE_ERROR_STATUS, s.hw_error)

    def _write(self, s: Servo, addr: int, data: bytes) -> int:
        """Apply a write to one servo; returns the status error byte."""
        eeprom = addr < CT.TORQUE_ENABLE[0]
        if eeprom and s.torque:
            return ERR_ACCESS
        if addr == CT.GOAL_POSITION[0] and len(data) == 4:
            goal = CT.signed(int.from_bytes(data, "little"), 4)
            apply = s.torque and not s.watchdog_fired and not s.hw_error
            if apply and self.t0 is None:
                self.t0 = time.monotonic()
                self.first_goal_t = self.now()
            self.goal_log.append((self.now(), s.i + 1, goal, apply))
            if apply:
                self.stepper.set_goal(s.i, goal - self.rest[s.i], self.now())
                s.mem[addr:addr + 4] = data
            return 0
        if addr == CT.TORQUE_ENABLE[0]:
            on = bool(data[0])
            if on and s.hw_error:
                return ERR_ACCESS
            self.stepper.set_torque(s.i, on, self.now())
        if addr == CT.BUS_WATCHDOG[0] and data[0] == 0:
            s.watchdog_fired = False
        s.mem[addr:addr + len(data)] = data
        return 0

    def _handle(self, dxl_id: int, inst: int, params: bytes, crc_ok: bool) -> None:
        if not crc_ok:
            return  # a servo ignores a packet whose CRC fails
        ids = range(1, 10) if dxl_id == BROADCAST else [dxl_id] if 1 <= dxl_id <= 9 else []
        if inst == PING:
            for i in ids:
                s = self.servos[i - 1]
                self._reply(i, 0, s.get(CT.MODEL_NUMBER).to_bytes(2, "little") + bytes([s.get((6, 1))]))
        elif inst == READ and dxl_id != BROADCAST:
            for i in ids:
                a, n = int.from_bytes(params[0:2], "little"), int.from_bytes(params[2:4], "little")
                s = self.servos[i - 1]
                self._refresh(s, a, n)
                self._reply(i, 0, bytes(s.mem[a:a + n]))
        elif inst == WRITE:
            a = int.from_bytes(params[0:2], "little")
            for i in ids:
                err = self._write(self.servos[i - 1], a, params[2:])
                if dxl_id != BROADCAST:
                    self._reply(i, err)
        elif inst == SYNC_READ:
            a, n = int.from_bytes(params[0:2], "little"), int.from_bytes(params[2:4], "little")
            for i in params[4:]:
                if 1 <= i <= 9:
                    s = self.servos[i - 1]
                    self._refresh(s, a, n)
                    self._reply(i, 0, bytes(s.mem[a:a + n]))
        elif inst == SYNC_WRITE:
            a, n = int.from_bytes(params[0:2], "little"), int.from_bytes(params[2:4], "little")
            rest = params[4:]
            for k in range(0, len(rest) - n, n + 1):
                i = rest[k]
                if 1 <= i <= 9:
                    self._write(self.servos[i - 1], a, rest[k + 1:k + 1 + n])

    # --- for tests and the trial rule ------------------------------------------------------------
    def torque_states(self) -> list[bool]:
        with self._lock:
            return [s.torque for s in self.servos]

    def goals(self) -> np.ndarray:
        """Every goal received: (n, 4) rows of trial time, id, goal, applied."""
        with self._lock:
            return np.array(self.goal_log, float).reshape(-1, 4)
