"""The raw tree's manifest: every group with the sha256 of each file."""

import json
import sys

from embodied_snap.lineage.records import tracked
from embodied_snap.rawformat import write_json

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    groups = [g for f in snakemake.input.shards for g in json.load(open(f))["groups"]]
    index = json.load(open(snakemake.input.index))
    write_json({"format_version": 1, "index": index, "groups": sorted(groups, key=lambda g: g["group_id"])}, snakemake.output[0])
