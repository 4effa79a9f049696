"""The robustness variants' targets: training, selection and evaluation drawn uniformly over the
measured workspace, and the training targets of the generations a continued run adds."""

import json
import sys

from embodied_snap.lineage.records import tracked
from embodied_snap.policy import targets

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    ws = json.load(open(snakemake.input.workspace))
    P = snakemake.params
    k = P.per_generation
    for name, n in P.uniform_sizes.items():
        df = targets.sample_uniform(ws, n, P.seeds[f"uniform_{name}"], P.arc_deg)
        if name == "training":  # generation g trains on rows g*k .. g*k+k-1, as in policy_targets
            df.insert(1, "generation", df.index // k)
        df.to_parquet(snakemake.output[f"uniform_{name}"], index=False)
        print("uniform", name, len(df), file=sys.stderr)
    # continued runs: generations G .. G'-1 on targets drawn like the benchmark's own training set
    g0, g1 = P.extension
    df = targets.sample(ws, (g1 - g0) * k, P.seeds["extension"], P.arc_deg, P.jitter_m)
    df.insert(1, "generation", g0 + df.index // k)
    df.to_parquet(snakemake.output.extension, index=False)
    print("extension", g0, g1, len(df), file=sys.stderr)
