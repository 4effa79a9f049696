"""The non-learned baseline: the best of the fixed primitives on the selection targets, evaluated."""

import sys

import numpy as np
import torch

from embodied_snap.io import read_parquet, write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search, simulate

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.for_job(I, P)
    prims = search.fixed_primitives(P.policy["fixed_primitives"], P.seed, P.policy["ranges"])
    k, r = search.best_fixed(sim, prims, search.Targets(read_parquet(I.selection), ws))
    T = search.Targets(read_parquet(I.evaluation), ws)
    act = {a: np.repeat(v, len(T)) for a, v in prims[k].items()}
    search.outcomes(sim, act, T, "fixed", -1).to_parquet(snakemake.output.eval, index=False)
    best = {a: float(v[0]) for a, v in prims[k].items()}
    print("best fixed primitive", k, best, float(r[k]), file=sys.stderr)
    write_json({"best": k, "params": best, "selection_reward": [float(x) for x in r]}, snakemake.output.summary)
