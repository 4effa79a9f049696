"""Acquisition on the simulated rig: one group = its program (embodied_snap.acquisition, the same
draws as the lab's plan), run on the simulated arm, written in the rig format.

A group's randomness comes from (seed, group_id) only, and its session's parameters from
(seed, session) only, so a group's bytes do not depend on which other groups share its job.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np
import pandas as pd

from .. import rawformat as RF
from ..acquisition import draws as D
from ..acquisition import programs as P
from ..protocol import Protocol
from ..quat import mat_apply, norm3
from . import mocap as MC
from . import servo as SV
from . import sim
from . import truth as TR

T0 = _dt.datetime(2026, 3, 2, 9, 0, 0)
BLOCK_HALF = tuple(s / 2 for s in D.BLOCK_SIZE_M)  # the acquisition's block; the cups strike its +Z face


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
    v = mat_apply(Ry, ns["vel"])
    n = -v / norm3(v)  # face normal points back at the incoming cup
    pos = mat_apply(Ry, ns["pos"]) + 0.03 * (-n) + offset
    z = n
    x = np.cross([0.0, 1.0, 0.0], z)
    x = x / norm3(x) if norm3(x) > 1e-6 else np.array([1.0, 0, 0])
    y = np.cross(z, x)
    R = np.stack([x, y, z], 1)
    from scipy.spatial.transform import Rotation

    qx = Rotation.from_matrix(R).as_quat()  # x, y, z, w
    quat = np.array([qx[3], qx[0], qx[1], qx[2]])
    pos = pos + n * BLOCK_HALF[2]  # centre of the block behind its face
    return dict(pos=pos, quat=quat, R=R, normal=np.array([0.0, 0.0, 1.0]), half=np.array(BLOCK_HALF))


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
    r, prog, off, goals, times, t_e = D.draw_group(row, seed, proto, dt)
    sess = TR.session_params(seed, session)
    arm = TR.arm_params(sess)
    sv = TR.servo_params(seed)
    target = None if off is None else place_target(prog["bearing"], off, dt, proto)
    shaft = SV.present_from_goal(goals, dt, np.array(sv["rate"]), np.array(sv["tau"]))
    wrench, held = None, {}
    if t_e is not None:
        wrench, held = hold_wrench(np.arange(1, len(goals) + 1) * dt, t_e, hold, r)
        prog.update(held)  # what the operator did (the label is when)
        held = dict(base_event_t=t_e)
    trial = sim.run(arm, shaft, dt, TR.LATCH, scene=sim.Scene(target=target, seal=TR.SEAL), wrench=wrench,
                    rate=np.array(sv["rate"]))
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
    meta = dict(
        format_version=RF.FORMAT_VERSION,
        group_id=gid,
        evidence_set=row["evidence_set"],
        category=row["category"],
        session=session,
        recorded_at=_recorded_at(gid, session),
        source="twin",
        **MC.base_meta(sess),
        program={k: (round(v, 4) if isinstance(v, float) else v) for k, v in prog.items()},
        labels=labels,
    )
    if target is not None:
        meta["target"] = dict(size_m=list(D.BLOCK_SIZE_M), face=D.BLOCK_FACE)
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
