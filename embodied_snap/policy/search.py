"""CMA-ES policy search (paper IV-B/IV-C, section V protocol) and the fixed-primitive baseline.

A policy maps a target to the six primitive parameters: canonical target (Eq. 5), features
g = (d, e, r) normalised by the training targets' statistics, network outputs (Eq. 6 or a
baseline), Eq. 7 decoding. CMA-ES (pycma) maximises the mean reward over each generation's
training targets; after every generation the CMA-ES mean is scored on the selection targets
(held-out reward, logged against simulator evaluations) and the best of those is selected.
"""

from __future__ import annotations

import pickle
from dataclasses import dataclass

import cma
import numpy as np
import pandas as pd
from scipy.stats import qmc
from tqdm import tqdm

from .. import bearing as BR
from . import geometry, networks
from .actions import decode
from .evaluations import evaluations

OUTCOME = ("lateral_m", "gap_m", "miss_m", "v_pk_mps", "t_pk_s", "t_ca_s", "reward", "c_h", "p_snap",
           "disagreement_m")


class Targets:
    """Canonical positions, normals and raw features of a target table."""

    def __init__(self, df: pd.DataFrame, ws: dict):
        n = np.asarray(ws["hanging_axis"])
        p = df[["x", "y", "z"]].to_numpy(float)
        self.df = df.reset_index(drop=True)
        self.p, rot = geometry.canonical(p, n, ws["phi0_deg"] + ws["delta_str_deg"])
        self.normal = BR.rotate(df[["nx", "ny", "nz"]].to_numpy(float), rot, n)
        self.g = geometry.features(self.p, n)

    def take(self, idx):
        t = object.__new__(Targets)
        t.df, t.p, t.normal, t.g = self.df.iloc[idx].reset_index(drop=True), self.p[idx], self.normal[idx], self.g[idx]
        return t

    def __len__(self):
        return len(self.p)


def feature_stats(train: Targets) -> dict:
    return {"mu": train.g.mean(0).tolist(), "sd": train.g.std(0).tolist()}


def normalised(g: np.ndarray, norm: dict) -> np.ndarray:
    """Raw target features g (N, 3) in a run's units: its training targets' statistics (`norm`)."""
    return (g - np.asarray(norm["mu"])) / np.asarray(norm["sd"])


def policy_actions(arch: str, theta, T: Targets, norm: dict, ranges: dict) -> dict:
    return decode(networks.outputs(arch, theta, normalised(T.g, norm)), ranges)


def score(sim, jobs: list[tuple[dict, Targets]]) -> np.ndarray:
    """Mean reward of each (commands, targets) pair, all as one batch of rollouts."""
    cat = {k: np.concatenate([a[k] for a, _ in jobs]) for k in jobs[0][0]}
    r = sim.run(cat, np.concatenate([T.p for _, T in jobs]), np.concatenate([T.normal for _, T in jobs]))["reward"]
    return np.array([x.mean() for x in np.split(r, np.cumsum([len(T) for _, T in jobs])[:-1])])


@dataclass(frozen=True)
class SearchSpec:
    """What every run of one search shares: its budget, where it starts and the commands' ranges."""

    ranges: dict  # config policy.ranges: the range of each command (Eq. 7)
    generations: int  # CMA-ES generations in all (a resumed run continues up to this budget)
    popsize: int  # CMA-ES candidates per generation
    start: dict  # where a run begins (`networks.initial`) and its initial step size sigma0
    # generation counts at which the selection so far is kept (`run["snapshots"]`): a run stopped
    # there selects exactly that policy, since CMA-ES does not depend on the total budget
    snapshots: tuple = ()


@dataclass(frozen=True)
class SearchTargets:
    """The targets a search trains and selects on."""

    train: Targets  # training targets
    gen_of: np.ndarray  # (len(train),) the generation each training target belongs to
    select: Targets  # selection targets: the mean after every generation is scored on them
    norm: dict  # the training targets' feature statistics (`feature_stats`); a resumed run keeps its own


class _Run:
    """One CMA-ES run's state between generations (see `cmaes`)."""

    def __init__(self, arch: str, seed: int, spec: SearchSpec, resume: dict | None, select: Targets, norm: dict):
        self.arch, self.seed, self.popsize, self.snapshots = arch, seed, spec.popsize, spec.snapshots
        self.select, self.norm, self.ranges = select, norm, spec.ranges
        if resume is None:
            start = spec.start
            self.es = cma.CMAEvolutionStrategy(networks.initial(arch, start, seed), start["sigma0"],
                                               {"popsize": spec.popsize, "verbose": -9, "maxiter": spec.generations,
                                                # its own generator: runs in lockstep draw apart
                                                "randn": np.random.RandomState(seed + 1).randn,
                                                "seed": np.nan})
            self.curve, self.best, self.snaps = [], (-np.inf, None, 0), {}
        else:  # the run's last held-out score is logged already
            self.es = pickle.loads(resume["state"])
            self.curve, self.snaps = [dict(c) for c in resume["curve"]], dict(resume.get("snapshots", {}))
            self.best = (resume["selection_reward"], np.asarray(resume["theta"]), resume["selected_generation"])
        self.pending = False  # the current mean's held-out score is not yet logged
        self.candidates = None

    def held_job(self):
        return policy_actions(self.arch, self.es.mean, self.select, self.norm, self.ranges), self.select

    def jobs(self, targets: Targets) -> list:
        """This generation's rollouts: its candidates on `targets`, then the previous mean's held-out score."""
        self.candidates = self.es.ask()
        jobs = [(policy_actions(self.arch, x, targets, self.norm, self.ranges), targets) for x in self.candidates]
        return jobs + [self.held_job()] if self.pending else jobs

    def tell(self, rewards: np.ndarray, gen: int, per_gen: int) -> float | None:
        held = None
        if self.pending:  # es.mean is still the mean after the previous generation
            held = self.log_held(float(rewards[-1]))
        pop = self.popsize
        self.es.tell(self.candidates, list(-rewards[:pop]))
        self.pending = True
        self.curve.append(dict(generation=gen + 1, evaluations=(gen + 1) * per_gen, heldout_reward=None,
                               train_reward_mean=float(rewards[:pop].mean()),
                               train_reward_best=float(rewards[:pop].max())))
        return held

    def log_held(self, held: float) -> float:
        mean = np.array(self.es.mean)
        self.curve[-1]["heldout_reward"] = held
        if held > self.best[0]:
            self.best = (held, mean, len(self.curve))
        if len(self.curve) in self.snapshots:
            self.snaps[str(len(self.curve))] = dict(selected_generation=self.best[2], selection_reward=self.best[0],
                                                    theta=self.best[1].tolist(), final_heldout_reward=held)
        return held

    def result(self, per_gen: int) -> dict:
        best, curve = self.best, self.curve
        return dict(arch=self.arch, seed=self.seed, n_params=networks.n_params(self.arch),
                    evaluations_per_generation=per_gen, curve=curve, selected_generation=best[2],
                    selection_reward=best[0], final_heldout_reward=curve[-1]["heldout_reward"],
                    theta=best[1].tolist(), norm=self.norm, snapshots=self.snaps, state=pickle.dumps(self.es))


def cmaes(sim, arch: str, seed: int, targets: SearchTargets, spec: SearchSpec, progress: bool = True,
          resume: dict | None = None) -> dict:
    """One CMA-ES run of architecture `arch` with optimisation seed `seed`.

    The held-out score of the mean after generation g rides in the batch of generation g + 1 (the
    mean that generation samples around), so each generation is one batch of rollouts.
    resume: a finished run (with its `state`) to continue up to `spec.generations` (a larger budget).
    The returned run carries `state` (bytes: the pickled CMA-ES object, with the run's own random
    generator, so a continuation in another process draws what the longer run would have) for such
    a continuation; it is not JSON and is written on its own."""
    return lockstep(sim, [(arch, seed, resume)], targets, spec, progress)[0]


def lockstep(sim, runs: list[tuple], targets: SearchTargets, spec: SearchSpec, progress: bool = True) -> list[dict]:
    """Several CMA-ES runs, (arch, seed, resume) each, on the same targets, a generation at a time:
    each generation's rollouts of every run are one batch (config policy.batch_runs, the schedule
    for a device with room for many populations at once). Each run samples from its own generator
    (seed + 1), so a run's result is `cmaes`'s for it alone, up to the floating-point effect of the
    batch on the rollouts; a resumed run's norm is its own."""
    gen_of = targets.gen_of
    rs = [_Run(a, s, spec, res, targets.select, res["norm"] if res else targets.norm) for a, s, res in runs]
    first = {len(r.curve) for r in rs}
    if len(first) != 1:
        raise ValueError(f"runs in lockstep start at one generation, not at {sorted(first)}")
    per_gen = evaluations(1, spec.popsize, int((gen_of == gen_of.min()).sum()))
    desc = f"{runs[0][0]} seed {runs[0][1]}" if len(rs) == 1 else f"{len(rs)} runs in lockstep"
    bar = tqdm(range(first.pop(), spec.generations), desc=desc, disable=not progress, mininterval=5)
    for gen in bar:
        gen_targets = targets.train.take(np.flatnonzero(gen_of == gen))
        jobs = [r.jobs(gen_targets) for r in rs]
        rewards = score(sim, [j for js in jobs for j in js])
        split = np.split(rewards, np.cumsum([len(js) for js in jobs])[:-1])
        held = [r.tell(x, gen, per_gen) for r, x in zip(rs, split)]
        if held[0] is not None:
            bar.set_postfix(heldout=f"{np.mean(held):.3f}")
    pending = [r for r in rs if r.pending]
    if pending:
        for r, held in zip(pending, score(sim, [r.held_job() for r in pending])):
            r.log_held(float(held))
    return [r.result(per_gen) for r in rs]


def at_budget(run: dict, generations: int) -> dict:
    """The run as if it had stopped after `generations` (one of its snapshots)."""
    s = run["snapshots"][str(generations)]
    return dict(run, curve=run["curve"][:generations], snapshots={}, **s)


def outcomes(sim, act: dict, T: Targets, arch: str, seed: int) -> pd.DataFrame:
    """Per-target strike of commands act on targets T, with the commands after all clamps."""
    out = sim.run(act, T.p, T.normal)
    df = pd.DataFrame({"target_id": T.df["target_id"], "arch": arch, "seed": seed,
                       "bearing_deg": T.df["bearing_deg"], "d_m": T.g[:, 0], "e_m": T.g[:, 1], "r_m": T.g[:, 2]})
    for k in ("rho1", "rho2", "rho3", "s3"):
        df[k] = out[k]
    df["dphi_deg"], df["tau_s"] = out["dphi"], out["tau"]
    for k in OUTCOME:
        df[k] = out[k]
    return df


def fixed_primitives(n: int, seed: int, ranges: dict) -> list[dict]:
    """n fixed parameter sets: a Latin hypercube over the six action ranges (u space, Eq. 7)."""
    u = qmc.LatinHypercube(d=6, rng=np.random.default_rng(seed)).random(n) * 2 - 1
    return [decode(u[i:i + 1], ranges) for i in range(n)]


def best_fixed(sim, prims: list[dict], select: Targets) -> tuple[int, np.ndarray]:
    """The fixed primitive with the highest mean reward on the selection targets."""
    r = score(sim, [({k: np.repeat(v, len(select)) for k, v in p.items()}, select) for p in prims])
    return int(np.argmax(r)), r
