"""Deployment trials on the simulated rig (paper VI): the block at a manifest placement, nine
virtual XM430s on a pseudo-terminal (vbus.py) whose shafts drive the arm (stepper.py), and
`esnap deploy`'s own code (embodied_snap.deploy.client) talking to them as to any serial port.

The bus runs in its own process (as the servos are other hardware: the client's busy polling of
the port must not starve it), the arm's physics live behind it. The block is a free body on its
support (truth.BLOCK). The client writes the servo log and meta.json of a complete trial; the rig
adds what its motion capture saw (240 Hz, mocap.py, the block included) and what the operator
observes: attached (the cup sealed on the block's face), retrieved (the block left its support and
was still on the cup at the end of the carry, measured from the motion capture: `retrieved`) and
snap_speed_event. An aborted trial
leaves only `aborted/<id>.json`, and no index row.
"""

from __future__ import annotations

import datetime as _dt
import json
import multiprocessing as mp
import os
from pathlib import Path

import numpy as np

from .. import rawformat as RF
from ..acquisition.draws import rng_for
from ..deploy import client
from ..io import parquet_rows
from . import mocap as MC
from . import truth as TR
from .acquire import BLOCK_HALF
from .stepper import Stepper
from .vbus import VirtualBus

T0 = _dt.datetime(2026, 5, 4, 9, 0, 0)  # the deployment day, after every acquisition session


def block_at(p, normal) -> dict:
    """The block with its struck (+z) face through the target point p, facing `normal`."""
    from scipy.spatial.transform import Rotation

    z = np.asarray(normal, float) / np.linalg.norm(normal)
    x = np.cross([0.0, 1.0, 0.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0, 0])
    R = np.stack([x, np.cross(z, x), z], 1)
    qx = Rotation.from_matrix(R).as_quat()
    return dict(pos=np.asarray(p, float) - z * BLOCK_HALF[2], quat=np.array([qx[3], qx[0], qx[1], qx[2]]), R=R,
                normal=np.array([0.0, 0.0, 1.0]), half=np.array(BLOCK_HALF))


def rig(man: dict, placement: int, session: str, seed: int, dt: float, gid: str, faults: dict | None = None):
    """(bus, stepper, target, session params, rng) for one trial; the bus is not started."""
    sess = TR.session_params(seed, session)
    pl = man["placements"][placement - 1]
    target = block_at(pl["target_m"], pl["normal"])
    r = rng_for(seed, "deployment", gid)
    arm = dict(TR.arm_params(sess), block_mass=TR.BLOCK["mass_kg"])
    st = Stepper(arm, TR.servo_params(seed), dt, TR.LATCH, target=target, seal=TR.SEAL, rng=r, block=TR.BLOCK)
    bus = VirtualBus(st, man["envelope"]["eeprom_min"], man["envelope"]["eeprom_max"], faults)
    return bus, st, target, sess, r


LEFT_M = 0.03  # m: the block left its support when the motion capture sees it this far from where it stood
HELD_S = 0.2  # s: at the end of the carry the block moved with the tip over this long ...
HELD_WITHIN_M = 0.3  # m: ... within this distance of it (cup 15 cm beyond the tip, block centre up to 9 cm beyond) ...
HELD_SPREAD_M = 0.02  # m: ... and that distance varied by less than this (a dropped block falls away)


def retrieved(mc) -> bool:
    """What the operator sees: the block left its support and was still on the cup at the end of
    the carry, from the motion capture (block and tip markers) alone."""
    ok = mc.target_valid.to_numpy(bool) & mc.tip_valid.to_numpy(bool)
    blk = mc[["target_x", "target_y", "target_z"]].to_numpy()[ok]
    tip = mc[["tip_x", "tip_y", "tip_z"]].to_numpy()[ok]
    t = mc.t.to_numpy()[ok]
    if len(t) < 2:
        return False
    left = np.linalg.norm(blk - blk[0], axis=1).max() > LEFT_M
    last = t >= t[-1] - HELD_S
    dist = np.linalg.norm(blk[last] - tip[last], axis=1)
    return bool(left and dist.max() < HELD_WITHIN_M and dist.max() - dist.min() < HELD_SPREAD_M)


def record(raw: Path, gid: str, st: Stepper, target: dict, sess: dict, r, session: str, k: int,
           t_end: float, speed_mps: float) -> dict:
    """Add the motion capture and the observed labels to a complete trial the client wrote."""
    trial, _ = st.finish(t_end)
    ev = trial.events
    calib = dict(base_pos=sess["base_pos"], base_quat=sess["base_quat"])
    mc = MC.mocap_frame(trial, calib, target, r)
    p = RF.group_paths(raw, gid)
    RF.write_parquet(mc, p["mocap"])
    meta = RF.read_meta(p["meta"])
    vtip = np.linalg.norm(np.diff(trial.pos[:, 2], axis=0), axis=1) / st.dt
    vtip = np.convolve(vtip, np.ones(4) / 4, mode="same")
    attached = ev["sealed"] is not None
    retained = retrieved(mc)
    meta.update(session=session, source="twin", recorded_at=(T0 + _dt.timedelta(seconds=120 * k)).isoformat(),
                **MC.base_meta(sess),
                target=dict(size_m=[2 * h for h in BLOCK_HALF], face="+z"))
    meta["labels"].update(attached=bool(attached), retrieved=bool(retained),
                          snap_speed_event=bool(vtip.max() >= speed_mps))
    if attached:
        meta["labels"]["t_attach"] = round(float(ev["sealed"]), 4)
    RF.write_json(meta, p["meta"])
    return dict(group_id=gid, evidence_set="deployment", category="placement", session=session,
                recorded_at=meta["recorded_at"], n_mocap=len(mc), n_servo=parquet_rows(p["servo"]))


def _serve(conn, man, placement, session, seed, dt, gid, faults, raw, k, speed_mps):
    """The rig's process: the bus until told the trial ended, then the physics and the mocap."""
    bus, st, target, sess, r = rig(man, placement, session, seed, dt, gid, faults)
    conn.send(bus.start())
    msg = conn.recv()  # ("done", t_end) or ("aborted", None)
    bus.stop()
    out = dict(goals=bus.goals(), torque=bus.torque_states(), stopped_at=bus.stopped_at,
               rx_bytes=bus.rx_bytes, tx_bytes=bus.tx_bytes)
    if msg[0] == "done":
        os.nice(5)  # the physics may wait; the other trial's bus may not
        out["row"] = record(Path(raw), gid, st, target, sess, r, session, k, msg[1], speed_mps)
    conn.send(out)


class RigProcess:
    """A rig in its own forked process, serving the virtual bus: `with rig as port:` (the bus's pty),
    then `finish(t_end)`. `serve(conn, *args)` sends the port, waits for ("done", t_end) or
    ("aborted", None), and sends back its record."""

    def __init__(self, serve, *args):
        ctx = mp.get_context("fork")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=serve, args=(child, *args), daemon=True)
        self.result = None

    def __enter__(self) -> str:
        self.proc.start()
        return self.conn.recv()

    def finish(self, t_end: float | None) -> dict:
        """Tell the rig the trial ended (t_end: the last servo-log time, None when aborted)."""
        if self.result is None:
            self.conn.send(("done", t_end) if t_end is not None else ("aborted", None))
            self.result = self.conn.recv()
            self.proc.join(30)
        return self.result

    def __exit__(self, *exc):
        self.finish(None)


class Rig(RigProcess):
    """The simulated rig of one deployment trial."""

    def __init__(self, man: dict, placement: int, k: int, raw, seed: int, n_sessions: int, dt: float,
                 speed_mps: float = 1.0, faults: dict | None = None):
        self.gid = f"{RF.PREFIX['deployment']}_{k:04d}"
        session = f"s{(k - 1) % n_sessions + 1:02d}"  # session variation: trials spread over the sessions
        super().__init__(_serve, man, placement, session, seed, dt, self.gid, faults, str(raw), k, speed_mps)


def run_trial(man_path, placement: int, k: int, raw, seed: int, n_sessions: int, dt: float, speed_mps: float,
              faults: dict | None = None, say=lambda s: None) -> dict:
    """Trial k (1-based) at a placement, through the virtual bus. Returns its index row, or
    {group_id, cause} when `esnap deploy` aborted (nothing enters the index then)."""
    with open(man_path) as f:
        man = json.load(f)
    rig_ = Rig(man, placement, k, raw, seed, n_sessions, dt, speed_mps, faults)
    with rig_ as port:
        try:
            res = client.run(man_path, port, man["placements"][placement - 1]["target_m"], out=raw,
                             group_id=rig_.gid, placement=placement, say=say)
        except client.DeployError as e:
            return dict(group_id=rig_.gid, cause=str(e))
        out = rig_.finish(float(res["log"][-1, 0]) + 0.005)
    return out["row"]
