"""Every characterisation number beside the paper's: results/characterize/claims.csv."""

import json
import sys

import pandas as pd

from embodied_snap.characterize.claims import OURS, rows
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    fits = {k: (snakemake.input[k], json.load(open(snakemake.input[k]))) for k in sorted({f for f, _ in OURS.values()})}
    df = pd.DataFrame(rows(fits))
    print(df.to_string(), file=sys.stderr)
    df.to_csv(snakemake.output[0], index=False, lineterminator="\n")
