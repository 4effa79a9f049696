"""The ablation's target sets: offset targets and release-evaluation targets, one seed each, in
target families (docs/ablation.md)."""

import json
import sys

from embodied_snap.ablation.targets import sample_families
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    ws = json.load(open(snakemake.input.workspace))
    P = snakemake.params
    for name, n in P.sizes.items():
        df = sample_families(ws, n, P.starts, P.seeds[name], P.arc_deg, P.jitter_m)
        df.to_parquet(snakemake.output[name], index=False)
        print(name, len(df), "targets in", df["family"].nunique(), "families", file=sys.stderr)
