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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import rawformat as RF
from ..acquisition.draws import rng_for
from ..deploy import client
from ..io import parquet_rows, write_json, write_parquet
from . import mocap as MC
from . import truth as TR
from .acquire import BLOCK_HALF
from .sim import Scene
from .stepper import Stepper
from .vbus import VirtualBus

T0 = _dt.datetime(2026, 5, 4, 9, 0, 0)  # the deployment day, after every acquisition session


@dataclass(frozen=True)
class DeploymentSetup:
    """What every deployment trial of a run shares."""

    raw: Path | str  # the deployment tree the trials are written into (groups/, aborted/)
    seed: int  # the twin's seed: session parameters, servos, noise streams
    n_sessions: int  # the trials are spread over this many sessions (session variation)
    dt: float  # physics step, s
    speed_mps: float  # tip speed at or above which the operator notes a snap_speed_event, m/s


@dataclass(frozen=True)
class RigParts:
    """One simulated rig as rig() builds it (here and in labrig.py); its bus is not started."""

    bus: VirtualBus  # the virtual Dynamixel bus on its pty
    stepper: Stepper  # the arm behind the bus, stepped live
    target: dict | None  # the block (sim.Scene.target), None: no target
    sess: dict  # the session's parameters (truth.session_params)
    rng: np.random.Generator  # the rig's noise stream
    push: object = None  # a held-base group's push (labrig.HeldBase), else None


def trial_id(k: int) -> str:
    """The group id of deployment trial k (1-based)."""
    return f"{RF.PREFIX['deployment']}_{k:04d}"


def trial_session(k: int, n_sessions: int) -> str:
    """The session of trial k: session variation, the trials spread over the sessions."""
    return f"s{(k - 1) % n_sessions + 1:02d}"


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


def rig(man: dict, placement: int, k: int, setup: DeploymentSetup, faults: dict | None = None) -> RigParts:
    """The rig of trial k at a placement; the bus is not started."""
    sess = TR.session_params(setup.seed, trial_session(k, setup.n_sessions))
    pl = man["placements"][placement - 1]
    target = block_at(pl["target_m"], pl["normal"])
    rng = rng_for(setup.seed, "deployment", trial_id(k))
    arm = dict(TR.arm_params(sess), block_mass=TR.BLOCK["mass_kg"])
    st = Stepper(arm, TR.servo_params(setup.seed), setup.dt, TR.LATCH,
                 scene=Scene(target=target, seal=TR.SEAL, block=TR.BLOCK), rng=rng)
    bus = VirtualBus(st, man["envelope"]["eeprom_min"], man["envelope"]["eeprom_max"], faults)
    return RigParts(bus=bus, stepper=st, target=target, sess=sess, rng=rng)


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


def record(parts: RigParts, setup: DeploymentSetup, k: int, t_end: float) -> dict:
    """Add the motion capture and the observed labels to complete trial k, which the client wrote."""
    gid, session, sess = trial_id(k), trial_session(k, setup.n_sessions), parts.sess
    trial, _ = parts.stepper.finish(t_end)
    ev = trial.events
    calib = dict(base_pos=sess["base_pos"], base_quat=sess["base_quat"])
    mc = MC.mocap_frame(trial, calib, parts.target, parts.rng)
    paths = RF.group_paths(Path(setup.raw), gid)
    write_parquet(mc, paths["mocap"])
    meta = RF.read_meta(paths["meta"])
    vtip = np.linalg.norm(np.diff(trial.pos[:, 2], axis=0), axis=1) / parts.stepper.dt
    vtip = np.convolve(vtip, np.ones(4) / 4, mode="same")
    attached = ev["sealed"] is not None
    retained = retrieved(mc)
    meta.update(session=session, source="twin", recorded_at=(T0 + _dt.timedelta(seconds=120 * k)).isoformat(),
                **MC.base_meta(sess),
                target=dict(size_m=[2 * h for h in BLOCK_HALF], face="+z"))
    meta["labels"].update(attached=bool(attached), retrieved=bool(retained),
                          snap_speed_event=bool(vtip.max() >= setup.speed_mps))
    if attached:
        meta["labels"]["t_attach"] = round(float(ev["sealed"]), 4)
    write_json(meta, paths["meta"])
    return dict(group_id=gid, evidence_set="deployment", category="placement", session=session,
                recorded_at=meta["recorded_at"], n_mocap=len(mc), n_servo=parquet_rows(paths["servo"]))


def _serve(conn, man: dict, placement: int, k: int, setup: DeploymentSetup, faults: dict | None):
    """The rig's process: the bus until told the trial ended, then the physics and the mocap."""
    parts = rig(man, placement, k, setup, faults)
    bus = parts.bus
    conn.send(bus.start())
    msg = conn.recv()  # ("done", t_end) or ("aborted", None)
    bus.stop()
    out = dict(goals=bus.goals(), torque=bus.torque_states(), stopped_at=bus.stopped_at,
               rx_bytes=bus.rx_bytes, tx_bytes=bus.tx_bytes)
    if msg[0] == "done":
        os.nice(5)  # the physics may wait; the other trial's bus may not
        out["row"] = record(parts, setup, k, msg[1])
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
    """The simulated rig of deployment trial k (1-based) at a placement."""

    def __init__(self, man: dict, placement: int, k: int, setup: DeploymentSetup, faults: dict | None = None):
        self.gid = trial_id(k)
        super().__init__(_serve, man, placement, k, setup, faults)


def run_trial(man_path, placement: int, k: int, setup: DeploymentSetup, faults: dict | None = None,
              say=lambda s: None) -> dict:
    """Trial k (1-based) at a placement, through the virtual bus. Returns its index row, or
    {group_id, cause} when `esnap deploy` aborted (nothing enters the index then)."""
    with open(man_path) as fh:
        man = json.load(fh)
    rig_ = Rig(man, placement, k, setup, faults)
    with rig_ as port:
        try:
            res = client.run(man_path, port, man["placements"][placement - 1]["target_m"], out=setup.raw,
                             group_id=rig_.gid, placement=placement, say=say)
        except client.DeployError as e:
            return dict(group_id=rig_.gid, cause=str(e))
        out = rig_.finish(float(res["log"][-1, 0]) + 0.005)
    return out["row"]
