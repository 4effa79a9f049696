"""Every number of the ablation paragraphs beside the paper's: results/ablation/claims.csv."""

import json
import sys

import pandas as pd

from embodied_snap.ablation.claims import rows
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    df = pd.DataFrame(rows((snakemake.input.summary, json.load(open(snakemake.input.summary)))))
    print(df.to_string(), file=sys.stderr)
    df.to_csv(snakemake.output[0], index=False, lineterminator="\n")
