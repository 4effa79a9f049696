"""The selected policy of one run on the evaluation targets (used by nothing before this job); with
params.generations, the policy the run had selected at that point (a smaller budget)."""

import json
import sys

import numpy as np
import torch

from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search, simulate

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.for_job(I, P)
    run = json.load(open(I.run))
    if P.get("generations"):
        run = search.at_budget(run, P.generations)
    T = search.Targets(read_parquet(I.evaluation), ws)
    act = search.policy_actions(run["arch"], np.asarray(run["theta"]), T, run["norm"], P.policy["ranges"])
    df = search.outcomes(sim, act, T, run["arch"], run["seed"])
    print(df[["miss_m", "v_pk_mps", "reward"]].describe(), file=sys.stderr)
    df.to_parquet(snakemake.output[0], index=False)
