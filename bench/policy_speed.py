"""One CMA-ES policy search on the paper budget (120 generations x 24 candidates x 48 targets,
3-seed ensemble, 72-step rollouts, held-out scoring on 64 targets every generation), timed.

    python bench/policy_speed.py RESULTS_DIR [--threads N] [--arch shared] [--generations 120]

RESULTS_DIR is a finished run's `results/` (it reads the dynamics models, the hold bank, P_snap,
the workspace and the training and selection targets, as `policy_search` does). Prints the wall
time of the run, seconds per generation and simulator evaluations per second.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import pandas as pd
import torch
import yaml

from embodied_snap.policy import search, simulate


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("results", type=Path)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--arch", default="shared")
    ap.add_argument("--generations", type=int, default=120)
    ap.add_argument("--config", type=Path, default=Path(__file__).resolve().parent.parent / "config.yaml")
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    cfg = yaml.safe_load(a.config.read_text())
    budget = cfg["budgets"]["paper"]["policy"]
    R = a.results
    sim, ws = simulate.from_files(sorted(map(str, R.glob("dynamics/models/seed*.pt"))), R / "dynamics/hold_bank.npz",
                                  R / "characterize/snap.json", R / "policy/workspace.json",
                                  simulate.SimSettings.from_config(cfg))
    tr = pd.read_parquet(R / "policy/targets_training.parquet")
    train = search.Targets(tr, ws)
    sel = search.Targets(pd.read_parquet(R / "policy/targets_selection.parquet"), ws)
    t0 = time.perf_counter()
    tgt = search.SearchTargets(train=train, gen_of=tr["generation"].to_numpy(), select=sel,
                               norm=search.feature_stats(train))
    spec = search.SearchSpec(ranges=cfg["policy"]["ranges"], generations=a.generations, popsize=budget["popsize"],
                             start=cfg["policy"]["start"])
    run = search.cmaes(sim, a.arch, 0, tgt, spec, progress=False)
    dt = time.perf_counter() - t0
    n = run["curve"][-1]["evaluations"]
    print(f"{a.arch}, {a.generations} generations x {budget['popsize']} x {budget['targets_per_candidate']} "
          f"({n:,} evaluations) on {a.threads} thread(s): {dt:.1f} s, {dt / a.generations:.3f} s/generation, "
          f"{n / dt:,.0f} evaluations/s; held-out reward {run['curve'][0]['heldout_reward']:.3f} -> "
          f"{run['curve'][-1]['heldout_reward']:.3f}")


if __name__ == "__main__":
    main()
