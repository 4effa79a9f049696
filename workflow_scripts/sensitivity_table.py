"""Per start: the architecture result, the reading and the slope probe: results/sensitivity/starts.csv."""

import json
import sys

import pandas as pd

from embodied_snap.lineage.records import tracked
from embodied_snap.paper import html
from embodied_snap.policy.sensitivity import claim_rows

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    rows = claim_rows(json.load(open(snakemake.input.summary)))
    df = pd.DataFrame(rows)
    print(df.to_string(), file=sys.stderr)
    df.to_csv(snakemake.output.csv, index=False, lineterminator="\n")
    with open(snakemake.output.html, "w") as f:
        f.write(html.table("The benchmark from each start", "docs/policy.md, Starting point.", list(df.columns), rows))
