"""Pre-release perturbation sweep of the selected policy on the evaluation targets, at multiples of
the hold model's leave-one-session-out error read from results/dynamics/hold.json."""

import json
import sys

import numpy as np
import torch

from embodied_snap.ablation import perturb
from embodied_snap.ablation.rollouts import selected_actions
from embodied_snap.io import read_parquet, write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search, simulate

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.for_job(I, P)
    H = json.load(open(I.hold))
    arm_mm = H["tip_mm_median"] / H["tip_pct_arm_median"] * 100  # the arm length hold.json reports against
    T = search.Targets(read_parquet(I.evaluation), ws)
    run, act = selected_actions(I.runs, T, P.policy["ranges"])
    spec = perturb.PerturbationSweep(scales=tuple(P.scales), draws=P.draws, err_mm=H["tip_mm_median"],
                                     err_deg=H["axis_deg_median"], arm_mm=arm_mm, seed=P.seed)
    rows = perturb.sweep(sim, act, T, spec, hanging_axis=np.asarray(ws["hanging_axis"]))
    for r in rows:
        print(r, file=sys.stderr)
    write_json({"seed": run["seed"], "error_tip_mm": H["tip_mm_median"], "error_axis_deg": H["axis_deg_median"],
                "arm_mm": arm_mm, "scales": rows}, snakemake.output[0])
