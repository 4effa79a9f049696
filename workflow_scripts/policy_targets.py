"""The simulated target sets: training (per generation), selection and evaluation, one seed each."""

import json
import sys

from embodied_snap.lineage.records import tracked
from embodied_snap.policy import targets

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    ws = json.load(open(snakemake.input.workspace))
    P = snakemake.params
    for name, n in P.sizes.items():
        df = targets.sample(ws, n, P.seeds[name], P.arc_deg, P.jitter_m)
        if name == "training":  # the targets_per_candidate of generation g are rows g*k .. g*k+k-1
            df.insert(1, "generation", df.index // P.per_generation)
        df.to_parquet(snakemake.output[name], index=False)
        print(name, len(df), file=sys.stderr)
