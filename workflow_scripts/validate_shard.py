"""Validate every recording of one shard; one line per broken rule, nothing half-written."""

import sys
from pathlib import Path

import pandas as pd

from embodied_snap.lineage.records import tracked
from embodied_snap.rawformat import write_json
from embodied_snap.validate import RecordingError, validate_shard

sys.stderr = open(snakemake.log[0], "w")
p = snakemake.params
try:
    with tracked(snakemake):
        index = pd.read_csv(snakemake.input.index, dtype=str)
        raw = Path(snakemake.input.index).parent
        entries = validate_shard(raw, p.groups, index)
        write_json({"shard": snakemake.wildcards.shard, "groups": entries}, snakemake.output[0])
except RecordingError as e:
    print(f"error: {e}", file=sys.stderr)
    sys.exit(f"error: {e}")
