"""Every architecture and generalisation number of sections V-A and V-B beside the paper's:
results/policy/claims.csv."""

import json
import sys

import pandas as pd

from embodied_snap.lineage.records import tracked
from embodied_snap.policy.claims import rows

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    df = pd.DataFrame(rows((snakemake.input.summary, json.load(open(snakemake.input.summary)))))
    print(df.to_string(), file=sys.stderr)
    df.to_csv(snakemake.output[0], index=False, lineterminator="\n")
