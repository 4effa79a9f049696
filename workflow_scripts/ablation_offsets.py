"""Event offsets delta of the three trigger rules, fitted on the offset targets only."""

import sys

import numpy as np
import torch

from embodied_snap.ablation import release
from embodied_snap.ablation.rollouts import rule_clock, selected_actions
from embodied_snap.io import read_parquet, write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search, simulate

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.for_job(I, P)
    T = search.Targets(read_parquet(I.offset), ws)
    run, act = selected_actions(I.runs, T, P.policy["ranges"])
    proto = rule_clock(sim, P.triggers, ws["hanging_axis"])
    t_e = release.events(sim, act, T, proto)
    steps, tab = release.table(sim, act, T, proto)
    lo, hi = P.offset_range_s
    deltas = np.round(np.arange(lo, hi + proto["dt"] / 2, proto["dt"]), 6)
    fit = release.fit_offsets(t_e, steps, tab, deltas, proto)
    print({r: v["delta_s"] for r, v in fit.items()}, file=sys.stderr)
    write_json({"seed": run["seed"], "n_targets": len(T), "deltas_s": deltas.tolist(), "objective": "reward",
                "rules": fit}, snakemake.output[0])
