"""raw_data/index.csv from what each acquisition shard recorded."""

import json
import sys

from embodied_snap.lineage.records import tracked
from embodied_snap.rawformat import write_index

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    rows = [r for f in snakemake.input.acquired for r in json.load(open(f))["groups"]]
    write_index(rows, snakemake.output[0])
