"""One acquisition group on the simulated rig, recorded the lab's way: its program played by the
lab's client (embodied_snap.deploy.client.drive, `esnap lab acquire`) over the virtual Dynamixel bus
(vbus.py), whose servos drive the arm live (stepper.py).

The arm is the group's session's (as twin acquisition's `simulate_group`), with the group's fixed
target (acquire.place_target) where it has one. The program starts when the bus hears its first
goal with torque on (`VirtualBus.first_goal_t`, on the trial clock); a held-base group's operator
pushes the mount (acquire.hold_wrench) from that start plus the group's cue. The rig keeps its own
noise stream, (seed, "lab", group_id): its recordings are the lab's kind, not byte-identical to twin
acquisition's. The client writes the servo log; the rig adds what its motion capture saw and what
the operator notes (attached, retrieved, snap_speed_event), as simulate_group does.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace

import numpy as np

from ..acquisition.draws import rng_for
from ..protocol import Protocol
from . import mocap as MC
from . import truth as TR
from .acquire import hold_wrench, place_target
from .deployment import RigParts, RigProcess
from .sim import Scene
from .stepper import Stepper
from .vbus import VirtualBus


class HeldBase:
    """The operator's push of a held-base group, on the program's clock: hold_wrench from cue_s,
    drawn once (before anything else uses the rig's stream). Called by the stepper with the trial
    time of each step; the program's start is the bus's first goal (`start()`, None before it)."""

    def __init__(self, cue_s: float, hold: dict, dt: float, rng: np.random.Generator):
        self.dt, self.cue_s = dt, float(cue_s)
        n = int(np.ceil((cue_s + 2 * hold["rise_s"] + max(hold["hold_s"])) / dt)) + 2
        self.w, self.held = hold_wrench(np.arange(1, n + 1) * dt, cue_s, hold, rng)
        self.start = lambda: None

    def __call__(self, t: float) -> dict | None:
        t0 = self.start()
        if t0 is None:
            return None
        k = int(round((t - t0) / self.dt)) - 1  # row k is program time (k + 1) dt
        if not 0 <= k < len(self.w["mount"]):
            return None
        return dict(mount=self.w["mount"][k], proximal=self.w["proximal"][k])


@dataclass(frozen=True)
class LabRigSetup:
    """What every group of a plan shares on the lab's simulated rig."""

    seed: int  # the twin's seed: session parameters, servos, the rig's noise streams
    dt: float  # physics step, s
    hold: dict  # the operator's push of held-base groups (acquire.hold_wrench)
    proto: Protocol  # the protocol: target placement, the snap speed threshold
    eeprom_min: list  # the servos' EEPROM position limits, ticks (the plan's envelope): lower ...
    eeprom_max: list  # ... and upper


def rig(group: dict, setup: LabRigSetup, faults: dict | None = None, target: dict | None = None,
        rest=None) -> RigParts:
    """The rig of one group; the bus is not started.
    `target`: the group's block when already placed (place_target), else placed here; `rest`: what
    the servos read at rest (VirtualBus; default 0, the straight hanging arm). With another rest the
    client's start ramp runs first, and the trial clock (the motion capture's, the push's) starts
    with the ramp, not the program: for tests of the start, not for recordings."""
    seed, dt = setup.seed, setup.dt
    gid, session = str(group["group_id"]), str(group["session"])
    sess = TR.session_params(seed, session)
    sv = TR.servo_params(seed)
    off = group.get("target_offset_m")
    if target is None and off is not None:
        target = place_target(group["program"]["bearing"], np.asarray(off, float), dt, setup.proto)
    rng = rng_for(seed, "lab", gid)
    push = None if group.get("cue_s") is None else HeldBase(group["cue_s"], setup.hold, dt, rng)
    st = Stepper(TR.arm_params(sess), sv, dt, TR.LATCH, scene=Scene(target=target, seal=TR.SEAL), rng=rng,
                 wrench=push)
    bus = VirtualBus(st, setup.eeprom_min, setup.eeprom_max, faults, rest=rest)
    if push is not None:
        push.start = lambda: bus.first_goal_t
    return RigParts(bus=bus, stepper=st, target=target, sess=sess, rng=rng, push=push)


def record(parts: RigParts, t_end: float, speed_mps: float) -> dict:
    """The motion capture (trial clock) and the operator's observations of a complete group."""
    target, sess, rng = parts.target, parts.sess, parts.rng
    trial, _ = parts.stepper.finish(t_end)
    ev = trial.events
    vtip = np.linalg.norm(np.diff(trial.pos[:, 2], axis=0), axis=1) / parts.stepper.dt
    vtip = np.convolve(vtip, np.ones(4) / 4, mode="same")
    attached = retrieved = None
    if target is not None:
        attached = ev["sealed"] is not None
        retrieved = bool(attached and rng.uniform() < 1.0 - ev.get("seal_tilt", 0.0) / 300.0)  # tilted seals leak
    calib = dict(base_pos=sess["base_pos"], base_quat=sess["base_quat"])
    mc = MC.mocap_frame(trial, calib, target, rng)
    return dict(mocap=mc, attached=attached, retrieved=retrieved,
                t_attach=None if ev["sealed"] is None else float(ev["sealed"]),
                **MC.base_meta(sess),
                snap_speed_event=bool(vtip.max() >= speed_mps), events=dict(ev))


def _serve(conn, group: dict, setup: LabRigSetup, faults: dict | None, target: dict | None, rest):
    """The rig's process: the bus until told the group ended, then the physics and the mocap."""
    parts = rig(group, setup, faults, target, rest)
    bus, push = parts.bus, parts.push
    conn.send(bus.start())
    msg = conn.recv()  # ("done", t_end) or ("aborted", None)
    bus.stop()
    out = dict(goals=bus.goals(), torque=bus.torque_states(), stopped_at=bus.stopped_at,
               first_goal_t=bus.first_goal_t, hold=None)
    if push is not None:
        out["hold"] = dict(push.held, base_event_t=push.cue_s)
    if msg[0] == "done":
        os.nice(5)  # the physics may wait; another group's bus may not
        out.update(record(parts, msg[1], setup.proto.thresholds.attach_speed_mps))
    conn.send(out)


class LabRig(RigProcess):
    """The simulated rig of one acquisition group in its own process: `with LabRig(...) as port:`
    (the virtual bus's pty), then `finish(t_end)` (the last servo-log time + 0.005 s, or None when
    the client aborted). finish returns the bus's record (goals: (n, 4) time, id, goal, applied;
    torque: the servos' torque states at the end; stopped_at; first_goal_t: the program's start on
    the trial clock; hold: a held-base group's push, else None) and, for a complete group, mocap
    (the rig format, trial clock), attached, retrieved, t_attach (target groups, else None), base,
    axis, snap_speed_event and the physics' events."""

    def __init__(self, group: dict, setup: LabRigSetup, faults: dict | None = None, rest=None):
        self.gid = str(group["group_id"])
        off = group.get("target_offset_m")
        # placed here: the nominal strike is simulated once per process, not once per group
        target = None if off is None else place_target(group["program"]["bearing"], np.asarray(off, float),
                                                       setup.dt, setup.proto)
        # the rig's process gets plain copies of what it was given
        setup = replace(setup, seed=int(setup.seed), dt=float(setup.dt), hold=dict(setup.hold),
                        eeprom_min=list(setup.eeprom_min), eeprom_max=list(setup.eeprom_max))
        super().__init__(_serve, dict(group), setup, faults, target, rest)
