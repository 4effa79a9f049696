"""Acquisition on the simulated rig: one group = draw its program, run it, write it in the rig format.

A group's randomness comes from (seed, group_id) only, and its session's parameters from
(seed, session) only, so a group's bytes do not depend on which other groups share its job.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np
import pandas as pd

from .. import rawformat as RF
from ..protocol import Protocol
from . import mocap as MC
from . import protocols as P
from . import servo as SV
from . import sim
from . import truth as TR

T0 = _dt.datetime(2026, 3, 2, 9, 0, 0)
BLOCK_HALF = (0.05, 0.03, 0.015)  # the 10 x 6 x 3 cm block; the cups strike its 10 x 6 face (+Z)


def _rot_y(deg: float) -> np.ndarray:
    """Rotation about the arm axis that turns bearing phi into phi + deg ((cos, 0, sin) convention)."""
    a = -np.deg2rad(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


_NOMINAL_STRIKE: dict = {}


def nominal_strike(dt: float, proto: Protocol) -> dict:
    """Where the operating-point snap's cup passes at peak speed (the canonical bearing), in the
    arm frame. One simulation per process, nominal parameters: the operator's reference placement."""
    key = (dt, proto.primitive.phi0_deg, proto.primitive.s2_ramp_s, proto.rig.rated_speed_tick_s)
    if key not in _NOMINAL_STRIKE:
        goals, _ = P.primitive(P.OPERATING, proto.primitive.phi0_deg, dt, proto)
        sv = TR.servo_params(0)
        pres = SV.present_from_goal(goals, dt, np.full(9, np.mean(sv["rate"])), np.full(9, SV.TAU_NOMINAL))
        tr = sim.run(dict(TR.M.NOMINAL), pres, dt, TR.LATCH)
        v = np.linalg.norm(np.diff(tr.cup, axis=0), axis=1) / dt
        v = np.convolve(v, np.ones(8) / 8, mode="same")
        k = int(np.argmax(v))
        vel = (tr.cup[k + 4] - tr.cup[k - 4]) / (8 * dt)
        _NOMINAL_STRIKE[key] = dict(pos=tr.cup[k].copy(), vel=vel)
    return _NOMINAL_STRIKE[key]


def place_target(bearing: float, offset: np.ndarray, dt: float, proto: Protocol) -> dict:
    """Block with its striking face toward the incoming cup, `offset` (m, arm frame) from the
    nominal strike point, a little beyond it so the cup arrives still fast."""
    ns = nominal_strike(dt, proto)
    Ry = _rot_y(bearing - proto.primitive.phi0_deg)
    v = Ry @ ns["vel"]
    n = -v / np.linalg.norm(v)  # face normal points back at the incoming cup
    pos = Ry @ ns["pos"] + 0.03 * (-n) + offset
    z = n
    x = np.cross([0.0, 1.0, 0.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0, 0])
    y = np.cross(z, x)
    R = np.stack([x, y, z], 1)
    from scipy.spatial.transform import Rotation

    qx = Rotation.from_matrix(R).as_quat()  # x, y, z, w
    quat = np.array([qx[3], qx[0], qx[1], qx[2]])
    pos = pos + n * BLOCK_HALF[2]  # centre of the block behind its face
    return dict(pos=pos, quat=quat, R=R, normal=np.array([0.0, 0.0, 1.0]), half=np.array(BLOCK_HALF))


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
    elif es == "held_base":
        prog.update(jit(150.0), tau=_uniform(r, box["tau"]))
    spread = 2.0 if es == "delay_sweep" else 20.0
    prog["bearing"] = float(proto.primitive.phi0_deg + r.uniform(-spread, spread) + prog["dphi"])
    return prog


def has_target(row: dict) -> bool:
    es, cat = row["evidence_set"], row["category"]
    return es in ("attachment", "delay_sweep") or (es == "dynamics" and cat in ("target", "sealed"))


def hold_wrench(t: np.ndarray, t_e: float, hold: dict, r: np.random.Generator) -> tuple[dict, dict]:
    """The operator's hold of a held-base trial (config twin.held_base): from t_e a force of
    mount_force_n on the mount and proximal_force_n on the proximal S1 segment, one random
    direction, rising and falling over rise_s (smoothstep), held hold_s in between."""
    u = r.normal(0, 1, 3)
    u = u / np.linalg.norm(u)
    fm, fp = r.uniform(*hold["mount_force_n"]), r.uniform(*hold["proximal_force_n"])
    dur = r.uniform(*hold["hold_s"])
    rise = hold["rise_s"]
    s = np.clip((t - t_e) / rise, 0, 1) * np.clip((t_e + 2 * rise + dur - t) / rise, 0, 1)
    s = s * s * (3 - 2 * s)
    w = dict(mount=s[:, None] * fm * u, proximal=s[:, None] * fp * u)
    return w, dict(hold_force_n=float(fm), hold_s=float(dur))


def simulate_group(
    row: dict, seed: int, proto: Protocol, dt: float, hold: dict
) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    gid, session = str(row["group_id"]), str(row["session"])
    r = TR.rng_for(seed, "group", gid)
    sess = TR.session_params(seed, session)
    arm = TR.arm_params(sess)
    sv = TR.servo_params(seed)
    prog = draw_program(row, r, proto)
    target = None
    if has_target(row):
        if row["evidence_set"] == "delay_sweep":
            off = r.normal(0, 0.01, 3)
        else:
            off = r.normal(0, 0.05, 3)
        target = place_target(prog["bearing"], off, dt, proto)
    if prog["kind"] == "burst":
        goals, times = P.burst(prog["section"], prog["bearing"], prog["amplitude"], dt)
    elif prog["kind"] == "direct":
        goals, times = P.direct_release(prog, prog["bearing"], dt, proto)
    else:
        goals, times = P.primitive(prog, prog["bearing"], dt, proto, ramp_s=prog.get("ramp_s", 0.0))
    shaft = SV.present_from_goal(goals, dt, np.array(sv["rate"]), np.array(sv["tau"]))
    wrench, held = None, {}
    if row["evidence_set"] == "held_base":
        t_e = round(float(r.uniform(times["t_preload"] + 0.5, times["t_s1"] + 0.6)), 4)
        wrench, held = hold_wrench(np.arange(1, len(goals) + 1) * dt, t_e, hold, r)
        prog.update(held)  # what the operator did (the label is when)
        held = dict(base_event_t=t_e)
    trial = sim.run(arm, shaft, dt, TR.LATCH, target=target, seal=TR.SEAL, wrench=wrench, rate=np.array(sv["rate"]))
    ev = trial.events
    # --- observed labels (what the operator notes on the rig) ---
    vtip = np.linalg.norm(np.diff(trial.pos[:, 2], axis=0), axis=1) / dt
    vtip = np.convolve(vtip, np.ones(4) / 4, mode="same")
    labels = dict(snap_speed_event=bool(vtip.max() >= proto.thresholds.attach_speed_mps))
    labels.update({k: round(float(v), 4) for k, v in times.items()})
    if target is not None:
        attached = ev["sealed"] is not None
        retain = attached and r.uniform() < 1.0 - ev.get("seal_tilt", 0.0) / 300.0  # tilted seals leak
        labels.update(attached=bool(attached), retrieved=bool(retain), t_attach=ev["sealed"])
    labels.update(held)
    # --- recordings ---
    calib = dict(base_pos=sess["base_pos"], base_quat=sess["base_quat"])
    mc = MC.mocap_frame(trial, calib, target, r)
    sl = MC.servo_frame(trial.t, goals, trial.present, trial.tension, r)
    R = MC.quat_to_mat(np.asarray(sess["base_quat"]))
    axis = R @ np.array([0.0, -1.0, 0.0])
    meta = dict(
        format_version=RF.FORMAT_VERSION,
        group_id=gid,
        evidence_set=row["evidence_set"],
        category=row["category"],
        session=session,
        recorded_at=_recorded_at(gid, session),
        source="twin",
        base=dict(pos=[float(x) for x in sess["base_pos"]], quat=[float(x) for x in sess["base_quat"]]),
        axis=[float(x) for x in axis / np.linalg.norm(axis)],
        program={k: (round(v, 4) if isinstance(v, float) else v) for k, v in prog.items()},
        labels=labels,
    )
    if target is not None:
        meta["target"] = dict(size_m=[2 * h for h in BLOCK_HALF], face="+z")
    return meta, mc, sl


def _recorded_at(gid: str, session: str) -> str:
    """Deterministic wall time: sessions on consecutive days, groups a few minutes apart."""
    k = int(gid.split("_")[-1])
    day = TR.session_index(session) - 1
    return (T0 + _dt.timedelta(days=day, seconds=90 * k)).isoformat()


def acquire_groups(
    groups: "pd.DataFrame",
    raw_dir: str | Path,
    seed: int,
    proto: Protocol,
    dt: float,
    hold: dict,
    progress: bool = True,
) -> list[dict]:
    """Simulate and write each group (rows: group_id, evidence_set, category, session; extra
    columns ignored) via rawformat.write_group under the protocol `proto` (its primitive, rig and
    thresholds sections), integrated at dt (config twin.dt), held-base events from `hold` (config
    twin.held_base). Returns one index row per group."""
    rows = groups.to_dict("records") if isinstance(groups, pd.DataFrame) else list(groups)
    it = rows
    if progress:
        from tqdm import tqdm

        it = tqdm(rows, desc="twin", unit="group")
    out = []
    for row in it:
        meta, mc, sl = simulate_group(row, seed, proto, dt, hold)
        RF.write_group(raw_dir, meta, mc, sl)
        out.append(
            dict(
                group_id=meta["group_id"],
                evidence_set=meta["evidence_set"],
                category=meta["category"],
                session=meta["session"],
                recorded_at=meta["recorded_at"],
                n_mocap=len(mc),
                n_servo=len(sl),
            )
        )
    return out
