"""Every recording of one shard through the gate (the same check the plan made); its manifest."""

import sys
from pathlib import Path

from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.validate import Limits, RecordingError, read_index, validate_shard

sys.stderr = open(snakemake.log[0], "w")
p = snakemake.params
limits = Limits(**p.gate)
try:
    with tracked(snakemake):
        raw = Path(snakemake.input.index).parent
        index = read_index(raw, limits.group_id_pattern)
        entries = validate_shard(raw, p.groups, index, limits)
        write_json({"shard": snakemake.wildcards.shard, "groups": entries}, snakemake.output[0])
except RecordingError as e:
    print(f"error: {e}", file=sys.stderr)
    sys.exit(f"error: {e}")
