"""From a target to the trial's nine goal traces (paper Eq. 5-8, III-B), from the manifest alone.

Eq. 5: the target is turned about the hanging axis to the canonical strike bearing phi0 + Delta_str
and described by g = (d, e, r); Eq. 6: the shared network on the normalised features; Eq. 7: the
outputs decoded into the action ranges; Eq. 8: the preloads clamped to the directional workspace,
the S1 delay projected onto the timing set. The commanded bearing turns the canonical command back
to the target's bearing. The schedule is the primitive (embodied_snap.primitive, the map the rig
and the policy simulator share): hang, preload ramp, settle, S3 slack, S2 over its ramp, S1 after
tau, then the carry (S1 pulls the cup back toward the arm axis and holds). Numpy only.
"""

from __future__ import annotations

import numpy as np

from ..policy import geometry, networks
from ..policy.actions import decode, project_timing, workspace_clamp
from ..primitive import cable_gains, release_goals, section_goals


class RefusedTarget(ValueError):
    """A target or a command the manifest does not allow: one line."""


def commands(man: dict, target) -> dict:
    """The six commands (after every clamp) for a target (x, y, z, base frame, m), and the
    commanded bearing. Refuses a target outside the workspace's feature box."""
    ws, pol, act_cfg = man["workspace"], man["policy"], man["actions"]
    n = np.asarray(ws["hanging_axis"], float)
    p = np.asarray(target, float).reshape(1, 3)
    pc, rot = geometry.canonical(p, n, ws["phi0_deg"] + ws["delta_str_deg"])
    g = geometry.features(pc, n)
    lo, hi = (np.asarray(man["target_box"][k]) for k in ("lo", "hi"))
    if not np.all((g[0] >= lo) & (g[0] <= hi)):  # written so that a NaN is outside too
        raise RefusedTarget(f"target {np.round(p[0], 3).tolist()} outside the workspace: (d, e, r) = "
                            f"{np.round(g[0], 3).tolist()} m, allowed {np.round(lo, 3).tolist()} .. "
                            f"{np.round(hi, 3).tolist()}")
    u = networks.outputs(pol["arch"], np.asarray(pol["theta"], float),
                         (g - np.asarray(pol["norm"]["mu"])) / np.asarray(pol["norm"]["sd"]))
    act = decode(u, act_cfg["ranges"])
    act = workspace_clamp(act, ws["phi0_deg"] + act["dphi"], ws, act_cfg["workspace_fraction"])
    act["tau"] = project_timing(act["tau"], act_cfg["timing_s"])
    out = {k: float(v[0]) for k, v in act.items()}
    out["bearing"] = float((ws["phi0_deg"] + out["dphi"] - rot[0]) % 360.0)
    return out


def schedule(man: dict, cmd: dict) -> tuple[np.ndarray, np.ndarray, dict]:
    """Every goal of the trial (T, 9) int ticks at the servo rate, their times (T,) and the phase
    times. Read-only: nothing may change a goal once the trial starts (open loop, Table II)."""
    prim, sch = man["primitive"], man["primitive"]["schedule"]
    hz = float(man["servos"]["hz"])
    rho = np.array([cmd["rho1"], cmd["rho2"], cmd["rho3"]])
    W = section_goals(rho, cmd["bearing"])
    dur = max(np.abs(W).max() / (sch["plan_margin"] * man["calibration"]["rated_speed_tick_s"]), 0.2)
    t_slack = sch["hang_s"] + dur + sch["settle_s"]
    t2 = t_slack + sch["s2_delay_s"]
    t1 = t2 + cmd["tau"]
    t_carry = t1 + sch["after_s1_s"]
    t_end = t_carry + sch["carry_s"] + sch["carry_hold_s"]
    t = np.arange(int(np.ceil(t_end * hz)) + 1) / hz
    goals = np.zeros((len(t), 9))
    ramp = (t >= sch["hang_s"]) & (t < sch["hang_s"] + dur)
    goals[ramp] = W * ((t[ramp] - sch["hang_s"]) / dur)[:, None]
    goals[(t >= sch["hang_s"] + dur) & (t < t_slack)] = W
    rel = t >= t_slack
    goals[rel] = release_goals(rho, cmd["s3"], cmd["bearing"], t[rel], t2, t1, prim["s2_ramp_s"])
    # the carry: S1 (and with it every cable that traverses S1) takes up toward the opposite bearing
    a = np.clip((t - t_carry) / sch["carry_s"], 0.0, 1.0)
    goals += (a * sch["carry_ticks"])[:, None] * np.tile(cable_gains(cmd["bearing"] + 180.0), 3)[None, :]
    goals = np.round(goals).astype(np.int64)
    goals.setflags(write=False)
    t.setflags(write=False)
    phases = dict(t_preload=sch["hang_s"], t_slack=round(t_slack, 4), t_s2=round(t2, 4), t_s1=round(t1, 4),
                  t_carry=round(t_carry, 4), t_end=round(float(t[-1]), 4))
    return goals, t, phases


def check_envelope(man: dict, goals: np.ndarray) -> None:
    """Refuse a schedule with any goal outside the manifest's envelope."""
    lo, hi = (np.asarray(man["envelope"][k], float) for k in ("goal_min", "goal_max"))
    bad = (goals < lo) | (goals > hi)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise RefusedTarget(f"command outside the envelope: servo {j + 1} goal {int(goals[k, j])} at step {k} "
                            f"(allowed {lo[j]:.0f} .. {hi[j]:.0f})")


def plan(man: dict, target) -> dict:
    """Commands, schedule and phases of one trial, all checked before anything moves."""
    cmd = commands(man, target)
    goals, t, phases = schedule(man, cmd)
    check_envelope(man, goals)
    return dict(commands=cmd, goals=goals, t=t, phases=phases)
