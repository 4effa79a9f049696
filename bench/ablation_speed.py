"""The ablation stage's rollouts at a chosen size (default: the paper budget, 100 offset targets,
400 release targets, 400 evaluation targets, 8 perturbation draws at 4 scales), timed.

    python bench/ablation_speed.py RESULTS_DIR [--threads N] [--offset 100] [--release 400] [--draws 8]

RESULTS_DIR is a finished run's `results/` (dynamics models, hold bank, P_snap, workspace, the
shared policy runs, hold.json). Targets are drawn here as ablation_targets draws them, so a smoke run's
results time the paper-sized stage: a rollout costs the same whatever budget trained the GRUs
(same architecture and horizon). Prints the wall time of each part as the rules run it (the
recorded-strike half of ablation_bend, Snakemake start-up and the summary, figure and claims jobs
are not included; they take seconds).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch
import yaml

from embodied_snap.ablation import perturb, release
from embodied_snap.ablation.rollouts import rollout, rule_clock, selected_run
from embodied_snap.ablation.targets import sample_families
from embodied_snap.policy import search, simulate


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("results", type=Path)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--offset", type=int, default=100)
    ap.add_argument("--release", type=int, default=400)
    ap.add_argument("--draws", type=int, default=8)
    ap.add_argument("--config", type=Path, default=Path(__file__).resolve().parent.parent / "config.yaml")
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    cfg = yaml.safe_load(a.config.read_text())
    P, A, R = cfg["policy"], cfg["ablation"], a.results
    sim, ws = simulate.from_files(sorted(map(str, R.glob("dynamics/models/seed*.pt"))), R / "dynamics/hold_bank.npz",
                                  R / "characterize/snap.json", R / "policy/workspace.json",
                                  simulate.SimSettings.from_config(cfg))
    run = selected_run([json.load(open(f)) for f in sorted(R.glob("policy/runs/shared_seed*.json"))])
    proto = rule_clock(sim, dict(s1_rate_deg_s=A["s1_rate_deg_s"], tip_speed_mps=A["tip_speed_mps"]),
                       ws["hanging_axis"])

    def targets(n, seed):
        T = search.Targets(sample_families(ws, n, A["starts_per_family"], seed, P["arc_deg"], P["target_jitter_m"]), ws)
        return T, search.policy_actions("shared", np.asarray(run["theta"]), T, run["norm"], P["ranges"])

    times = {}
    t0 = time.perf_counter()
    T, act = targets(a.offset, A["target_seeds"]["offset"])
    t_e = release.events(sim, act, T, proto)
    steps, tab = release.table(sim, act, T, proto)
    lo, hi = A["offset_range_s"]
    fit = release.fit_offsets(t_e, steps, tab, np.round(np.arange(lo, hi + proto["dt"] / 2, proto["dt"]), 6), proto)
    times["ablation_offsets"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    T, act = targets(a.release, A["target_seeds"]["release"])
    t_e = release.events(sim, act, T, proto)
    steps, tab = release.table(sim, act, T, proto)
    release.compare(T, steps, tab, release.release_times(act["tau"], t_e, fit, A["clock_s"]), proto)
    times["ablation_rules"] = time.perf_counter() - t0

    T, act = targets(a.release, P["target_seeds"]["evaluation"])  # stands in for the evaluation set
    t0 = time.perf_counter()
    rollout(sim, act, T.p, T.normal, states=True)
    times["ablation_bend (model half)"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    H = json.load(open(R / "dynamics/hold.json"))
    spec = perturb.PerturbationSweep(scales=tuple(A["perturbation_scales"]), draws=a.draws,
                                     err_mm=H["tip_mm_median"], err_deg=H["axis_deg_median"],
                                     arm_mm=H["tip_mm_median"] / H["tip_pct_arm_median"] * 100, seed=cfg["seed"])
    perturb.sweep(sim, act, T, spec, hanging_axis=np.asarray(ws["hanging_axis"]))
    times["ablation_perturb"] = time.perf_counter() - t0

    n_roll = (a.offset + a.release) * (1 + len(steps)) + a.release * (1 + len(A["perturbation_scales"]) * a.draws + 1)
    for k, v in times.items():
        print(f"{k:28s} {v:7.1f} s")
    total = sum(times.values())
    print(f"{'total (one thread, serial)':28s} {total:7.1f} s  ({n_roll} rollouts, {n_roll / total:.0f} per s)")


if __name__ == "__main__":
    main()
