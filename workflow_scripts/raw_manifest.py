"""The raw tree's manifest: every group with the sha256 of each file."""

import json
import sys

from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    groups = [g for f in snakemake.input.shards for g in json.load(open(f))["groups"]]
    index = json.load(open(snakemake.input.index))
    # Groups the user excluded (raw_data.exclude) are named with their reason: left out on purpose.
    excluded = [{"group_id": g, "reason": r} for g, r in sorted(snakemake.params.excluded.items())]
    write_json({"format_version": 1, "index": index, "groups": sorted(groups, key=lambda g: g["group_id"]),
                **({"excluded": excluded} if excluded else {})}, snakemake.output[0])
