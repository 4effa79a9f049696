"""The group split (train/validation/sealed), written once from the group list and the seed."""

import sys

import pandas as pd

from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    df = pd.DataFrame(snakemake.params.split).sort_values("group_id")
    df.to_csv(snakemake.output[0], index=False)
    print(df.role.value_counts().to_string(), file=sys.stderr)
