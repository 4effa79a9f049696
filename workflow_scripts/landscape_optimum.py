"""Per target, the best six commands CMA-ES finds on them directly, in two independent repeats:
results/landscape/optimum.parquet (the best repeat's strike, and both repeats' rewards)."""

import sys

import numpy as np
import torch

from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import landscape, search, simulate
from embodied_snap.policy.actions import decode

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.for_job(I, P)
    ev = read_parquet(I.evaluation)
    T = search.Targets(ev.head(P.size["targets"]), ws)
    m, ranges = P.method, P.policy["ranges"]
    spec = landscape.OptimumSpec(popsize=m["popsize"], sigma0=m["sigma0"], generations=P.size["generations"],
                                 restarts=P.size["restarts"])
    rep = [landscape.optimum(sim, T, ranges, spec, s) for s in m["seeds"]]
    R = np.stack([r for _, r in rep])
    k = R.argmax(0)
    u = np.stack([u for u, _ in rep])[k, np.arange(len(T))]
    df = search.outcomes(sim, decode(u, ranges), T, "optimum", -1)
    for j in range(len(rep)):
        df[f"reward_repeat{j}"] = R[j]
    diff = np.abs(R[0] - R[1])
    print(f"{len(T)} targets: optimum {df.reward.mean():.4f}; repeats {R.mean(1).round(4)}; |difference| median "
          f"{np.median(diff):.4f}, p95 {np.quantile(diff, 0.95):.4f}, max {diff.max():.4f}", file=sys.stderr)
    df.to_parquet(snakemake.output[0], index=False)
