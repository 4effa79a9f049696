"""The deployment control loop on the virtual Dynamixel bus (docs/benchmarks.md, "Deployment").

One cycle of `esnap deploy`: sync write of nine goals, sync read of nine present current/velocity/
position blocks, one Hardware Error Status read. Reports the achieved period's jitter (p50/p99 of
|period - nominal|) at 50 and 100 Hz, the bytes on the wire per cycle (both directions, counted by
the bus) and the time they take at 1 Mbps (10 bits a byte) on the real bus. The bus runs in its own
process, as the servos are other hardware.

    python bench/deploy_loop.py [--cycles 400]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import time

import numpy as np

from embodied_snap.deploy import controltable as CT
from embodied_snap.deploy.client import Bus
from embodied_snap.twin import model as M
from embodied_snap.twin import truth as TR
from embodied_snap.twin.stepper import Stepper
from embodied_snap.twin.vbus import VirtualBus

LIMITS = ([-20000] * 9, [20000] * 9)


def serve(conn):
    st = Stepper(dict(M.NOMINAL), dict(rate=[3100.0] * 9, tau=[0.03] * 9), 0.001, TR.LATCH)
    bus = VirtualBus(st, *LIMITS)
    conn.send(bus.start())
    conn.recv()
    conn.send((bus.rx_bytes, bus.tx_bytes))
    bus.stop()


def loop(bus: Bus, hz: float, cycles: int) -> np.ndarray:
    period = 1.0 / hz
    t = np.empty(cycles)
    t0 = time.monotonic()
    for k in range(cycles):
        delay = t0 + k * period - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        t[k] = time.monotonic()
        bus.sync_write(np.full(9, 100 * (k % 20)))
        bus.sync_read()
        bus.read(1 + k % 9, CT.HARDWARE_ERROR_STATUS)
    return t


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cycles", type=int, default=400)
    a = ap.parse_args()
    ctx = mp.get_context("fork")
    here, there = ctx.Pipe()
    proc = ctx.Process(target=serve, args=(there,), daemon=True)
    proc.start()
    port = here.recv()
    bus = Bus(port, 1_000_000, range(1, 10), retries=2, reply_ms=20.0)
    for i in range(1, 10):
        bus.write(i, CT.TORQUE_ENABLE, 1)
    busy = []
    for hz in (50, 100):
        t = loop(bus, hz, a.cycles)
        jit = np.abs(np.diff(t) - 1 / hz) * 1e3
        t1 = time.monotonic()
        loop(bus, 1e6, 50)  # back to back: the cycle's own duration
        busy.append((time.monotonic() - t1) / 50 * 1e3)
        print(f"{hz:>3} Hz: period jitter p50 {np.percentile(jit, 50):.2f} ms, p99 {np.percentile(jit, 99):.2f} ms, "
              f"max {jit.max():.2f} ms over {a.cycles} cycles")
    here.send("bytes")
    rx, tx = here.recv()
    n = 2 * a.cycles + 100 + 9
    per = (rx + tx) / n
    print(f"bytes per cycle: {per:.0f} (to the servos {rx / n:.0f}, back {tx / n:.0f}); at 1 Mbps "
          f"{per * 10 / 1e3:.2f} ms of a {1e3 / 100:.0f} ms cycle at 100 Hz; cycle on the virtual bus "
          f"{np.mean(busy):.2f} ms back to back")
    bus.close()
    proc.join(5)


if __name__ == "__main__":
    main()
