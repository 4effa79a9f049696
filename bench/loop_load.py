"""The deployment control loop under CPU load (docs/benchmarks.md, "The control loop under load").

Runs the 18 trials of the paper budget (6 placements x 3, two at a time) the way the workflow's
`twin_deployment` does: each trial's rig (twin/deployment.py: the virtual Dynamixel bus and the
arm's physics in their own process) and `esnap deploy`'s client (deploy/client.py) on its
pseudo-terminal; the recorded trials then go through the recording gate (deploy/trials.py). First
quiet, then with `--load N` busy-loop processes that the script starts (each ends by itself after
`--load-s`; the script stops them as soon as the trials are done). It prints per phase:

- control period: the interval between the starts of consecutive cycles (sync write), p50/p99/max
- reply latency: one sync read of the nine servos, question to last reply, p50/p99/max
- the largest servo-log gap (what the gate checks against gate.max_servo_gap_s)
- lost replies (a reply timeout, retried), aborted trials (and their causes), trials the gate rejects
- the load average (1 min) before and after

The manifest is built as the tests build theirs (a synthetic shared policy and workspace), with the
config's `deployment:` settings: the paper's schedule (about 8.5 s a trial), 100 Hz, 20 ms reply
timeout, 100 ms watchdog. The timings are taken by wrapping the client's Bus and dynamixel-sdk's
reply paths here, so the same script measures any version of the client.

    python bench/loop_load.py [--load 5] [--phases quiet,load] [--trials 18]
    python bench/loop_load.py --phases load --pty   # only the pseudo-terminal's own round trip, under load
    ESNAP_REALTIME=0 python bench/loop_load.py   # the priority step disabled (as without permission)
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import resource
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from embodied_snap import protocol  # noqa: E402
from embodied_snap.deploy import client  # noqa: E402
from embodied_snap.deploy import manifest as MF  # noqa: E402
from embodied_snap.deploy import trials as T  # noqa: E402
from embodied_snap.policy import geometry, networks  # noqa: E402
from embodied_snap.twin.deployment import DeploymentSetup, Rig  # noqa: E402
from embodied_snap.validate import Limits  # noqa: E402

CFG = yaml.safe_load(open(ROOT / "config.yaml"))

# --- instrumentation (per worker process; reset at each trial) ---------------------------------------
_T = dict(start=[], latency=[], lost=0)


def _instrument() -> None:
    dxl = client._sdk()
    sync_write, sync_read = client.Bus.sync_write, client.Bus.sync_read
    grp_rx, ph_rx = dxl.GroupSyncRead.txRxPacket, dxl.Protocol2PacketHandler.txRxPacket
    lost = (dxl.COMM_RX_TIMEOUT, dxl.COMM_RX_FAIL)

    def timed_write(self, goals):
        _T["start"].append(time.monotonic())
        return sync_write(self, goals)

    def timed_read(self, *a):
        t = time.monotonic()
        out = sync_read(self, *a)
        _T["latency"].append(time.monotonic() - t)
        return out

    def counted_grp(self):
        r = grp_rx(self)
        _T["lost"] += r in lost
        return r

    def counted_ph(self, port, txpacket):
        out = ph_rx(self, port, txpacket)
        _T["lost"] += out[1] in lost
        return out

    client.Bus.sync_write, client.Bus.sync_read = timed_write, timed_read
    dxl.GroupSyncRead.txRxPacket, dxl.Protocol2PacketHandler.txRxPacket = counted_grp, counted_ph


def manifest(d: Path) -> Path:
    """The tests' synthetic policy and workspace (tests/test_deploy.py), the config's deployment settings."""
    rng = np.random.default_rng(3)
    n = np.array([0.0, -1.0, 0.0])
    b = np.deg2rad(rng.uniform(195, 235, 60))
    r, y = rng.uniform(0.45, 0.75, 60), rng.uniform(-0.7, -0.2, 60)
    P = np.stack([r * np.cos(b), y, r * np.sin(b)], 1)
    D = np.tile([0.6, -0.6, 0.5], (60, 1))
    ws = dict(hanging_axis=n.tolist(), phi0_deg=210.0, delta_str_deg=5.0, n_strikes=60,
              strike_points_m=P.round(5).tolist(), strike_dirs=(D / np.linalg.norm(D, axis=1)[:, None]).tolist(),
              bin_lo_deg=160.0, bin_width_deg=10.0, rho_max=[[3600.0, 3250.0, 3550.0]] * 11)
    g = geometry.features(P, n)
    run = dict(arch="shared", seed=0, n_params=networks.n_params("shared"), selection_reward=0.4,
               selected_generation=3, theta=rng.normal(0, 0.3, networks.n_params("shared")).tolist(),
               norm=dict(mu=g.mean(0).tolist(), sd=g.std(0).tolist()))
    (d / "run.json").write_text(json.dumps(run))
    proto = protocol.params(CFG, "primitive", "rig")
    n_pl = CFG["budgets"]["paper"]["deployment"]["placements"]
    dcfg = dict(CFG["deployment"], policy=CFG["policy"], n_placements=n_pl)
    man = MF.build({"policy_run": d / "run.json"}, run, ws, dict(lever_ticks_per_rad=[2300, 1450, 1440],
                   ceiling_rad_s=[1.3, 2.1, 2.1]), dcfg, proto, {}, {})
    p = d / "manifest.json"
    p.write_text(json.dumps(man))
    return p


def trial(man_path, raw, placement: int, k: int) -> dict:
    """One trial as twin.deployment.run_trial runs it, with the cycle timings."""
    _T.update(start=[], latency=[], lost=0)
    man = json.loads(Path(man_path).read_text())
    setup = DeploymentSetup(raw=raw, seed=CFG["seed"], n_sessions=CFG["sessions"], dt=CFG["twin"]["dt"],
                            speed_mps=CFG["characterize"]["attach_speed_mps"])
    rig = Rig(man, placement, k, setup)
    out = dict(start=None, latency=None, servo_t=None)
    with rig as port:
        try:
            res = client.run(man_path, port, man["placements"][placement - 1]["target_m"], out=raw,
                             group_id=rig.gid, placement=placement, say=lambda s: None)
            out["row"] = rig.finish(float(res["log"][-1, 0]) + 0.005)["row"]
            out["servo_t"] = res["log"][:, 0]
        except client.DeployError as e:
            out["row"] = dict(group_id=rig.gid, cause=str(e))
        except Exception as e:  # noqa: BLE001 (a crash of the client counts as an abort here)
            out["row"] = dict(group_id=rig.gid, cause=f"crashed: {type(e).__name__}: {e}")
    out.update(start=np.array(_T["start"]), latency=np.array(_T["latency"]), lost=_T["lost"])
    return out


def _busy(until: float) -> None:
    while time.monotonic() < until:
        pass


def start_load(n: int, seconds: float, target: float, warm_s: float) -> list:
    """n busy-loop processes, each ending by itself after `seconds`; waits (at most warm_s) until the
    1-minute load average reaches `target`."""
    ctx = mp.get_context("fork")
    until = time.monotonic() + seconds
    procs = [ctx.Process(target=_busy, args=(until,), daemon=True) for _ in range(n)]
    for p in procs:
        p.start()
    t_end = time.monotonic() + warm_s
    while os.getloadavg()[0] < target and time.monotonic() < t_end:
        time.sleep(1)
    return procs


def stop_load(procs) -> None:
    for p in procs:
        p.terminate()
    for p in procs:
        p.join(5)


def _echo(fd: int) -> None:
    client.realtime(41, say=None)
    while (d := os.read(fd, 64)) != b"q":
        os.write(fd, d * 10)  # 10 bytes in, 100 out: about one sync read's worth


def pty_roundtrip(seconds: float = 30.0) -> None:
    """The kernel's part of a reply: two processes under SCHED_FIFO (where permitted) ping-pong over a
    pseudo-terminal, no Python threads or physics beside them."""
    import select
    import tty

    m, s = os.openpty()
    tty.setraw(m)
    tty.setraw(s)
    echo = mp.get_context("fork").Process(target=_echo, args=(m,), daemon=True)
    echo.start()
    client.realtime(40, say=None)
    rtt, t_end = [], time.monotonic() + seconds
    while time.monotonic() < t_end:
        t, got = time.monotonic(), 0
        os.write(s, b"0123456789")
        while got < 100:
            select.select([s], [], [], 0.1)
            got += len(os.read(s, 200))
        rtt.append(time.monotonic() - t)
        time.sleep(0.005)
    os.write(s, b"q")
    echo.join(5)
    r = np.array(rtt)
    print(f"pty round trip (10 bytes out, 100 back), {len(r)} in {seconds:.0f} s: {pct(r)}; over 10 ms: "
          f"{int((r > 0.01).sum())}; load average {os.getloadavg()[0]:.2f}")


def pct(x: np.ndarray, unit=1e3) -> str:
    if len(x) == 0:
        return "n/a"
    return f"p50 {np.percentile(x, 50) * unit:.2f}, p99 {np.percentile(x, 99) * unit:.2f}, max {x.max() * unit:.2f} ms"


def phase(name: str, man_path: Path, work: Path, n_trials: int) -> dict:
    raw = work / name
    n_pl = CFG["budgets"]["paper"]["deployment"]["placements"]
    plan = [((k - 1) % n_pl + 1, k) for k in range(1, n_trials + 1)]  # interleaved, as twin_deployment
    la0 = os.getloadavg()
    t0 = time.monotonic()
    with ProcessPoolExecutor(2, mp_context=mp.get_context("fork")) as pool:
        res = list(pool.map(trial, [man_path] * len(plan), [raw] * len(plan), [p for p, _ in plan],
                            [k for _, k in plan]))
    wall = time.monotonic() - t0
    la1 = os.getloadavg()
    rows, rejected = T.gate(raw, [r["row"] for r in res], Limits.from_config(CFG))
    period = np.concatenate([np.diff(r["start"]) for r in res if len(r["start"]) > 1])
    latency = np.concatenate([r["latency"] for r in res])
    gaps = [np.diff(r["servo_t"]).max() for r in res if r["servo_t"] is not None]
    aborted = [r["row"] for r in res if "cause" in r["row"]]
    n_rej = len(rejected) - len(aborted)
    print(f"[{name}] {n_trials} trials in {wall:.1f} s, load average (1/5/15 min) before "
          f"{la0[0]:.2f}/{la0[1]:.2f}/{la0[2]:.2f}, after {la1[0]:.2f}/{la1[1]:.2f}/{la1[2]:.2f}")
    print(f"[{name}]   control period (nominal 10 ms): {pct(period)}")
    print(f"[{name}]   reply latency (sync read of 9):  {pct(latency)}")
    gate = CFG["gate"]["max_servo_gap_s"]
    print(f"[{name}]   largest servo-log gap: {max(gaps, default=0) * 1e3:.1f} ms (gate {gate * 1e3:.0f} ms); "
          f"trials with a gap over it: {sum(g > gate for g in gaps)}")
    print(f"[{name}]   lost replies (timeouts, retried): {sum(r['lost'] for r in res)}; aborted: {len(aborted)}; "
          f"rejected by the gate: {n_rej}; recorded: {len(rows)}/{n_trials}")
    labels = [json.loads((raw / "groups" / r["group_id"] / "meta.json").read_text())["labels"] for r in rows]
    print(f"[{name}]   outcomes of the recorded trials (to compare runs): "
          + ", ".join(f"{k} {sum(lb[k] for lb in labels)}" for k in ("attached", "retrieved", "snap_speed_event")))
    for a in rejected:
        print(f"[{name}]     {a['group_id']}: {a['cause']}")
    sys.stdout.flush()
    return dict(recorded=len(rows), aborted=len(aborted), rejected=n_rej)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--load", type=int, default=5, help="busy-loop processes in the load phase")
    ap.add_argument("--load-target", type=float, default=4.0, help="wait for this 1-min load average first")
    ap.add_argument("--warm-s", type=float, default=90.0, help="... but at most this long")
    ap.add_argument("--phases", default="quiet,load")
    ap.add_argument("--trials", type=int, default=18)
    ap.add_argument("--pty", action="store_true", help="measure only the pseudo-terminal's round trip")
    a = ap.parse_args()
    _instrument()
    print(f"cpus {os.cpu_count()}, ESNAP_REALTIME={os.environ.get('ESNAP_REALTIME', '(unset)')}, "
          f"uid {os.getuid()}, RLIMIT_RTPRIO {resource.getrlimit(resource.RLIMIT_RTPRIO)[0]}")
    with tempfile.TemporaryDirectory(prefix="loop_load_") as d:
        d = Path(d)
        man_path = manifest(d)
        for name in a.phases.split(","):
            procs = []
            try:
                if name == "load":
                    # bounded: ends by itself after the warm-up and twice a phase's expected time
                    procs = start_load(a.load, a.warm_s + 20 * a.trials, a.load_target, a.warm_s)
                    print(f"[load] {a.load} busy loops, load average {os.getloadavg()[0]:.2f} when the trials start")
                pty_roundtrip() if a.pty else phase(name, man_path, d, a.trials)
            finally:
                stop_load(procs)


if __name__ == "__main__":
    main()
