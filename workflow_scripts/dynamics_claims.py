"""Every number of section IV-A beside the paper's: results/dynamics/claims.csv."""

import json
import sys

import pandas as pd

from embodied_snap.dynamics.claims import rows
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    i = snakemake.input
    res = {k: (i[k], json.load(open(i[k]))) for k in ("persistence", "sealed", "gate", "hold")}
    res["validation"] = [(p, json.load(open(p))) for p in i.validation]
    df = pd.DataFrame(rows(res))
    print(df.to_string(), file=sys.stderr)
    df.to_csv(snakemake.output[0], index=False, lineterminator="\n")
