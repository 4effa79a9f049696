"""Rollouts of the ablation on the policy stage's simulator (policy.simulate.Simulator): the same
clamps, hold start, goal map, batched ensemble rollout, strike and reward as Simulator.run, with
three additions it does not need: a release time chosen by a rule instead of the policy's tau,
a rollout with S1 held (for event times), and a perturbed pre-release state. The ensemble-mean
arm state (s1, s2, tip, axis) comes back for the kinematic analyses.
"""

from __future__ import annotations

import json

import numpy as np

from .. import bearing as BR
from ..dynamics import hold
from ..dynamics.model import AXIS, TIP
from ..policy import reward as RW
from ..policy import search
from ..policy.analysis import selected_seed
from ..primitive import release_goals
from .triggers import release_step

ARM = slice(0, 12)  # s1, s2, tip, axis
OUTCOMES = ("reward", "lateral_m", "gap_m", "miss_m", "v_pk_mps")


def _tile(act: dict, m: int) -> dict:
    return {k: np.tile(np.asarray(v), m) for k, v in act.items()}


def _simulate(sim, act: dict, *, t_rel=None, held: bool = False, steps: int | None = None, perturb=None):
    """The commands, their hold cost and the ensemble rollout, as Simulator.run makes them: what
    rollout and held_rollout share."""
    act = dict(act)
    if t_rel is not None:
        act["tau"] = np.asarray(t_rel, float)
    act = sim.commands(act)
    H = steps if steps is not None else sim.H
    t_u = sim.anchor_s + sim.dt * np.arange(-sim.history, H + sim.ens.lookahead)  # as Simulator.t_u
    rho = np.stack([act["rho1"], act["rho2"], act["rho3"]], -1)
    t1 = np.full(len(rho), np.inf) if held else act["tau"]
    U = release_goals(rho, act["s3"], sim.phi0 + act["dphi"], t_u, 0.0, t1, sim.s2_ramp)
    xs, c_h = hold.start(sim.bank, act, U[:, :sim.history + 1])
    if perturb is not None:
        xs = perturb(xs)
    return act, c_h, sim.ens.rollout(xs, U[:, 1:], H, parts=(ARM,))


def rollout(sim, act: dict, p, normal, *, t_rel=None, perturb=None, states: bool = False) -> dict:
    """Commands act {name: (N,)} on canonical targets p, normals (N, 3), struck and scored. t_rel
    (N,) replaces the policy's tau (projected onto T as always). perturb(xs) -> xs edits the
    pre-release history. states: add the ensemble-mean arm state (N, H+1, 12)."""
    act, c_h, out = _simulate(sim, act, t_rel=t_rel, perturb=perturb)
    x = out["mean_parts"][0]
    res = dict(act, c_h=c_h, x=x) if states else dict(act, c_h=c_h)
    tip, axis = x[..., TIP], x[..., AXIS]
    cup = tip + sim.ee_m * axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    k_s1 = release_step(act["tau"], sim.anchor_s, sim.dt)
    s = RW.strike(cup, tip, p, normal, k_s1, sim.dt)
    p_snap = sim.snap.predict(act["rho1"], act["rho2"])
    dis = out["disagreement"].mean(-1)
    res.update(s, reward=RW.reward(s, c_h, p_snap, dis, sim.cfg["reward"]), k_s1=k_s1,
               k_ca=np.rint(s["t_ca_s"] / sim.dt).astype(int))
    return res


def held_rollout(sim, act: dict, steps: int) -> dict:
    """Commands act {name: (N,)} with S1 kept loaded for `steps` steps (no strike is scored): the
    commands, their hold cost and the ensemble-mean arm state x (N, steps+1, 12)."""
    act, c_h, out = _simulate(sim, act, held=True, steps=steps)
    return dict(act, c_h=c_h, x=out["mean_parts"][0])


def rule_clock(sim, triggers: dict, hanging_axis) -> dict:
    """What the release rules work on: the simulator's grid step, anchor and timing set, the
    trigger thresholds (config ablation) and the measured hanging axis."""
    return dict(triggers, dt=sim.dt, anchor_s=sim.anchor_s, timing=sim.timing, hanging_axis=list(hanging_axis))


def release_table(sim, act: dict, T, times: np.ndarray) -> dict:
    """Outcomes (N, len(times)) of every target released at each of `times` (one per admissible
    release step), as one batch of rollouts."""
    m, N = len(times), len(T)
    out = rollout(sim, _tile(act, m), np.tile(T.p, (m, 1)), np.tile(T.normal, (m, 1)),
                  t_rel=np.repeat(times, N))
    return {k: np.asarray(out[k]).reshape(m, N).T for k in OUTCOMES}


def perturbation(rng, n: int, pos_m: float, axis_deg: float, hanging_axis) -> callable:
    """A random rigid error of the pre-release configuration (the hold model's kind of error): the
    tip moved by pos_m in a uniformly random direction, the section ends by the same vector scaled
    by their share of the arm's chord length (the base stays put), and the tip axis turned by
    axis_deg about a random direction perpendicular to it. The same error for all history frames,
    so the history's velocities are unchanged."""
    d = rng.normal(size=(n, 3))
    d = pos_m * d / np.linalg.norm(d, axis=1, keepdims=True)
    w = rng.normal(size=(n, 3))

    def apply(xs):
        xs = np.array(xs, copy=True)
        last = xs[:, -1]
        L = np.stack([np.linalg.norm(last[:, 0:3], axis=1), np.linalg.norm(last[:, 3:6] - last[:, 0:3], axis=1),
                      np.linalg.norm(last[:, 6:9] - last[:, 3:6], axis=1)], 1)
        share = np.cumsum(L, 1) / L.sum(1, keepdims=True)
        for i, sl in enumerate((slice(0, 3), slice(3, 6), TIP)):
            xs[:, :, sl] += (share[:, i, None] * d)[:, None]
        a = last[:, AXIS] / np.linalg.norm(last[:, AXIS], axis=1, keepdims=True)
        r = np.cross(a, w)
        r /= np.linalg.norm(r, axis=1, keepdims=True)
        for j in range(n):  # Rodrigues about r_j, one rotation per start
            R = BR.rotation(np.array([axis_deg]), r[j])[0] if axis_deg else np.eye(3)
            xs[j, :, AXIS] = xs[j, :, AXIS] @ R.T
        return xs.astype(np.float32)

    return apply


def selected_actions(run_files, T, ranges: dict) -> tuple[dict, dict]:
    """The selected shared policy's run (from its CMA-ES run files) and its commands for targets T."""
    run = selected_run([json.load(open(f)) for f in run_files])
    return run, search.policy_actions("shared", np.asarray(run["theta"]), T, run["norm"], ranges)


def selected_run(runs: list[dict]) -> dict:
    """The selected shared policy (policy.analysis.selected_seed: best on the selection targets)."""
    seed = selected_seed(runs)
    return next(r for r in runs if r["arch"] == "shared" and r["seed"] == seed)
