"""The architecture result on the benchmark and each robustness variant: results/robustness/variants.csv."""

import json
import sys

import pandas as pd

from embodied_snap.lineage.records import tracked
from embodied_snap.policy.robustness import claim_rows
from embodied_snap.reference import paper_column

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    rows = claim_rows(json.load(open(snakemake.input.summary)), paper_column("policy", snakemake.input.reference))
    df = pd.DataFrame(rows)
    print(df.to_string(), file=sys.stderr)
    df.to_csv(snakemake.output[0], index=False, lineterminator="\n")
