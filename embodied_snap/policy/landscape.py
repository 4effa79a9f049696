"""What the landscape allows (docs/policy.md, "Landscape"): the per-target optimum of the six commands,
and what it says about the architectures apart from their search.

- `optimum`: per target, CMA-ES (pycma) directly on the six dimensionless commands u of Eq. 7
  (bounds [-1, 1]: the policies' box), the same simulator and reward, restarted from uniform random
  points; every target's candidates of one generation are one batch of rollouts.
- `actions.effective_u` (beside Eq. 7, which it inverts): the u that decodes to the commands the
  simulator applied (after the workspace clamp and the timing projection), so that a command above
  its clamp, where the reward is flat, is read at the clamp.
- `section_slopes`: the optimal preloads regressed on the standardised target features (d, e, r),
  one slope vector per section, and the F-test of one common slope against three (statsmodels).
- `fit_architecture`: an architecture fitted by least squares to the optimal u (torch L-BFGS), its policy
  then scored with the reward: capacity apart from search.
"""

from __future__ import annotations

from dataclasses import dataclass

import cma
import numpy as np
import pandas as pd
import statsmodels.api as sm
from tqdm import tqdm

from .actions import decode, effective_u
from .architectures import BY_NAME
from .networks import ACTIONS, initial, n_params, outputs

U_MAX = 0.99  # a least-squares target on the box's edge would need infinite tanh weights


@dataclass(frozen=True)
class OptimumSpec:
    """The per-target CMA-ES of `optimum` (config landscape: method and size)."""

    popsize: int  # candidates per generation, for each target
    sigma0: float  # initial step size in u
    generations: int  # generations of each restart
    restarts: int  # restarts from uniform random points


def optimum(sim, T, ranges: dict, spec: OptimumSpec, seed: int,
            progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(u (N, 6), reward (N,)): the best candidate any restart evaluated, per target of T."""
    n, popsize = len(T), spec.popsize
    best_u, best_r = np.zeros((n, 6)), np.full(n, -np.inf)
    rng = np.random.default_rng(seed)
    idx = np.repeat(np.arange(n), popsize)  # each target's candidates side by side in one batch
    bar = tqdm(total=spec.restarts * spec.generations, desc=f"optimum seed {seed}", disable=not progress,
               mininterval=5)
    for _ in range(spec.restarts):
        es = [cma.CMAEvolutionStrategy(rng.uniform(-1, 1, 6), spec.sigma0,
                                       {"popsize": popsize, "bounds": [-1, 1], "verbose": -9,
                                        "seed": int(rng.integers(1, 2**31 - 1))}) for _ in range(n)]
        for _ in range(spec.generations):
            cands = np.array([e.ask() for e in es])  # (n, popsize, 6)
            act = decode(cands.reshape(-1, 6), ranges)
            rewards = sim.run(act, T.p[idx], T.normal[idx])["reward"].reshape(n, popsize)
            for i, e in enumerate(es):
                e.tell(list(cands[i]), list(-rewards[i]))
            j = rewards.argmax(1)
            better = rewards[np.arange(n), j] > best_r
            best_r[better] = rewards[np.arange(n), j][better]
            best_u[better] = cands[np.arange(n), j][better]
            bar.update()
        bar.set_postfix(mean=f"{best_r.mean():.3f}")
    bar.close()
    return best_u, best_r


def standardise(g: np.ndarray) -> np.ndarray:
    return (g - g.mean(0)) / g.std(0)


def section_slopes(u: np.ndarray, g: np.ndarray) -> dict:
    """The optimal preloads (u of rho1, rho2, rho3) on the standardised features z = (d, e, r):
    per section its slope vector and R^2; the cosines between sections' slopes; and the F-test of
    one common slope (section intercepts, shared slopes) against one slope per section. Also the
    other commands' R^2 (S1's aim dphi and timing tau, S3's slack)."""
    z = standardise(g)
    n = len(z)
    fits = {a: sm.OLS(u[:, j], sm.add_constant(z)).fit() for j, a in enumerate(ACTIONS)}
    out = {"commands": {a: dict(slope=f.params[1:].tolist(), r2=float(f.rsquared), p=float(f.f_pvalue))
                        for a, f in fits.items()}}
    out["sections"] = {f"s{i}": dict(slope=c["slope"], r2=c["r2"], p_slope=c["p"])
                       for i, c in ((i, out["commands"][f"rho{i}"]) for i in (1, 2, 3))}
    slopes = [fits[f"rho{i}"].params[1:] for i in (1, 2, 3)]
    cos = lambda a, b: float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))  # noqa: E731
    out["cosine"] = {f"s{i + 1}s{j + 1}": cos(slopes[i], slopes[j]) for i, j in ((0, 1), (0, 2), (1, 2))}
    y = np.concatenate([u[:, ACTIONS.index(f"rho{i}")] for i in (1, 2, 3)])
    sec = np.kron(np.eye(3), np.ones((n, 1)))  # one intercept per section
    common = sm.OLS(y, np.hstack([sec, np.tile(z, (3, 1))])).fit()
    distinct = sm.OLS(y, np.hstack([sec, np.hstack([sec[:, [k]] * np.tile(z, (3, 1)) for k in range(3)])])).fit()
    f, p, df = distinct.compare_f_test(common)
    out["common_vs_distinct"] = dict(f=float(f), p=float(p), df_diff=float(df), r2_common=float(common.rsquared),
                                     r2_distinct=float(distinct.rsquared))
    return out


def fit_architecture(arch: str, g_norm: np.ndarray, u: np.ndarray, starts: int, seed: int) -> tuple[np.ndarray, float]:
    """theta minimising the mean squared error of the architecture's outputs to u (clipped to
    +-U_MAX): the best of `starts` full-batch L-BFGS fits (torch, float64) from Glorot-uniform
    starts; returns (theta, rms error in u)."""
    import torch

    G = torch.tensor(g_norm, dtype=torch.float64)
    U = torch.tensor(np.clip(u, -U_MAX, U_MAX), dtype=torch.float64)
    best = (np.inf, None)
    for k in range(starts):
        th = torch.tensor(initial(arch, {"init": "glorot", "init_seed": seed}, k), requires_grad=True)
        opt = torch.optim.LBFGS([th], max_iter=1000, tolerance_grad=1e-12, tolerance_change=1e-15, history_size=50,
                                line_search_fn="strong_wolfe")

        def loss(opt=opt, th=th):
            opt.zero_grad()
            e = ((outputs(arch, th, G) - U) ** 2).mean()
            e.backward()
            return e

        opt.step(loss)
        with torch.no_grad():
            e = float(((outputs(arch, th, G) - U) ** 2).mean())
        if e < best[0]:
            best = (e, th.detach().numpy().copy())
    return best[1], float(np.sqrt(best[0]))


APPLIED = {"rho1": "rho1", "dphi": "dphi_deg", "tau": "tau_s", "rho2": "rho2", "rho3": "rho3", "s3": "s3"}


def _stats(x) -> dict:
    x = np.asarray(x, float)
    return dict(mean=float(x.mean()), sd=float(x.std(ddof=1)) if len(x) > 1 else None, n=int(len(x)))


def summarize(sim, opt, T, evals, ranges: dict, seed: int, fit_starts: int = 3):
    """opt: the optimum's strikes (landscape_optimum), T: their targets in that order, evals: the
    benchmark's evaluation rows (and the fixed primitive's). Returns (summary dict, table)."""
    u = effective_u({a: opt[c].to_numpy() for a, c in APPLIED.items()}, ranges)
    R = opt[[c for c in opt.columns if c.startswith("reward_repeat")]].to_numpy()
    diff = np.abs(R[:, 0] - R[:, 1])
    ids = set(opt.target_id)
    mine = evals[evals.target_id.isin(ids)]
    g_norm = standardise(T.g)
    rows = []
    for arch in [a for a in BY_NAME if a in set(mine.arch)] + ["fixed"]:
        per_seed = mine[mine.arch == arch].groupby("seed").reward.mean()
        row = dict(arch=arch, n_targets=len(ids), optimum_reward=float(opt.reward.mean()),
                   searched_reward_mean=float(per_seed.mean()),
                   searched_reward_sd=float(per_seed.std(ddof=1)) if len(per_seed) > 1 else None,
                   n_seeds=int(len(per_seed)), n_params=None, lsq_reward=None, lsq_rms_u=None)
        if arch in BY_NAME:
            theta, rms = fit_architecture(arch, g_norm, u, fit_starts, seed)
            out = sim.run(decode(outputs(arch, theta, g_norm), ranges), T.p, T.normal)
            row.update(n_params=n_params(arch), lsq_reward=float(out["reward"].mean()), lsq_rms_u=rms)
        row["gain_to_optimum"] = row["optimum_reward"] - row["searched_reward_mean"]
        rows.append(row)
    table = pd.DataFrame(rows)
    summary = dict(
        n_targets=len(ids),
        optimum=dict(reward=_stats(opt.reward), repeats=[_stats(R[:, j]) for j in range(R.shape[1])],
                     repeat_difference=dict(median=float(np.median(diff)), p95=float(np.quantile(diff, 0.95)),
                                            max=float(diff.max()), mean=float(diff.mean())),
                     u_at_bound_fraction={a: float((np.abs(u[:, j]) >= 1 - 1e-6).mean())
                                          for j, a in enumerate(ACTIONS)}),
        sections=section_slopes(u, T.g),
        architectures=rows,
    )
    return summary, table
