"""Per start: the architecture result, the reading and the slope probe: results/sensitivity/starts.csv."""

from embodied_snap.lineage import records  # noqa: F401 -- first, so every read of the job is watched

# isort: split

import json
import sys

import pandas as pd

from embodied_snap.lineage.records import tracked
from embodied_snap.policy.sensitivity import claim_rows

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    df = pd.DataFrame(claim_rows(json.load(open(snakemake.input.summary))))
    print(df.to_string(), file=sys.stderr)
    df.to_csv(snakemake.output[0], index=False, lineterminator="\n")
