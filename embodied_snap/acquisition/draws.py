"""The per-group draws of the acquisition protocol: which program a group runs, where its target
stands relative to the nominal strike, and when a held-base trial's hand pushes.

A group's draws come from (seed, group_id) only, one stream per group taken in a fixed order
(program, target offset, held-base cue), so a group's program does not depend on which other groups
share its job, and the simulated rig and the lab's plan (`esnap lab plan`) draw the same programs.
"""

from __future__ import annotations

import zlib

import numpy as np

from ..protocol import Protocol
from . import programs as P

BLOCK_SIZE_M = (0.10, 0.06, 0.03)  # the target block; the cups strike its 10 x 6 cm face
BLOCK_FACE = "+z"  # that face, in the block's own axes (meta.json's target.face)
TARGET_SD_M = dict(delay_sweep=0.01)  # the sweep keeps one placement; other target sets spread 5 cm
TARGET_SD_DEFAULT_M = 0.05


def rng_for(seed: int, *key) -> np.random.Generator:
    """Independent stream per key: strings hashed with crc32 (stable across runs and machines)."""
    ints = [int(seed)] + [zlib.crc32(str(k).encode()) for k in key]
    return np.random.default_rng(ints)


def group_stream(seed: int, gid: str) -> np.random.Generator:
    return rng_for(seed, "group", gid)


def _uniform(r, box):
    return float(r.uniform(*box))


def draw_program(row: dict, r: np.random.Generator, proto: Protocol) -> dict:
    """The commanded program of one group (what the operator chose); dynamics groups draw from
    the policy's action ranges."""
    box = proto.primitive.ranges
    es, cat = row["evidence_set"], row["category"]
    n = int(str(row["group_id"]).split("_")[-1])
    op = P.OPERATING
    jit = lambda s: {k: float(op[k] + r.normal(0, s)) for k in ("rho1", "rho2", "rho3")}  # noqa: E731
    if es == "servo_calibration":
        return dict(
            kind="burst",
            section=int(r.integers(1, 4)),
            bearing=float(r.uniform(0, 360)),
            amplitude=float(r.uniform(400, 3000)),
        )
    if es == "release_mode" and cat == "direct":
        # shallow tip curl (below the fold angle): a purely tendon-driven release
        return dict(
            kind="direct",
            rho1=float(r.uniform(2600, 3000)),
            rho2=float(r.uniform(2200, 2600)),
            rho3=float(r.uniform(650, 1000)),
            s3=0.0,
            dphi=0.0,
            tau=0.0,
            bearing=float(r.uniform(190, 230)),
        )
    prog = dict(kind="primitive", s3=float(op["s3"]), dphi=0.0, tau=float(op["tau"]), **jit(60.0))
    if es == "release_mode":
        prog.update(jit(120.0), tau=_uniform(r, box["tau"]))  # the timing set
        if cat == "ramped":
            prog.update(kind="ramped", ramp_s=float(r.uniform(1.0, 6.0)))
        else:
            prog.update(kind="instantaneous")
    elif es == "delay_sweep":
        # one placement, the operating point held: only the delay changes
        prog.update(jit(25.0), tau=P.sweep_tau(n))
    elif es == "attachment":
        prog.update(jit(150.0), tau=float(r.uniform(0.40, 0.70)))
    elif es == "dynamics":
        if cat in ("free_space", "target", "sealed"):
            prog.update({k: _uniform(r, box[k]) for k in ("rho1", "rho2", "rho3", "dphi", "tau")})
            prog["s3"] = float(box["s3"][1] * r.uniform(0, 1) ** 2)  # quadratic map: dense near 0
        elif cat == "pilot":
            prog.update(jit(200.0), tau=float(r.uniform(0.3, 0.8)))
        elif cat == "characterisation":
            prog.update(rho1=_uniform(r, box["rho1"]), rho2=_uniform(r, box["rho2"]))
        prog["record_s"] = round(P.dynamics_record_s(proto), 4)  # drawn from no stream
    elif es == "held_base":
        prog.update(jit(150.0), tau=_uniform(r, box["tau"]))
    spread = 2.0 if es == "delay_sweep" else 20.0
    prog["bearing"] = float(proto.primitive.phi0_deg + r.uniform(-spread, spread) + prog["dphi"])
    return prog


def has_target(row: dict) -> bool:
    es, cat = row["evidence_set"], row["category"]
    return es in ("attachment", "delay_sweep") or (es == "dynamics" and cat in ("target", "sealed"))


def target_offset(row: dict, r: np.random.Generator) -> np.ndarray | None:
    """Where the operator places the target, m in the arm frame, from the nominal strike point
    (None: the group has no target)."""
    if not has_target(row):
        return None
    return r.normal(0, TARGET_SD_M.get(row["evidence_set"], TARGET_SD_DEFAULT_M), 3)


def held_base_cue(times: dict, r: np.random.Generator) -> float:
    """When the hand pushes the mount in a held-base trial, s on the program's clock: from half a
    second into the preload to 0.6 s after the S1 release."""
    return round(float(r.uniform(times["t_preload"] + 0.5, times["t_s1"] + 0.6)), 4)


def draw_group(row: dict, seed: int, proto: Protocol, dt: float):
    """(stream, program, target offset or None, goals, phase times, held-base cue or None) of one
    group; the stream continues with whatever executes the program (the simulated rig's noise)."""
    r = group_stream(seed, str(row["group_id"]))
    prog = draw_program(row, r, proto)
    off = target_offset(row, r)
    goals, times = P.goals_of(prog, dt, proto)
    cue = held_base_cue(times, r) if row["evidence_set"] == "held_base" else None
    return r, prog, off, goals, times, cue
