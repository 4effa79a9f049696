"""index.csv against the group folders (ids, sets, files, row counts); no recording in two groups."""

import json
import sys
from pathlib import Path

from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.validate import Limits, RecordingError, check_one_recording, validate_index

sys.stderr = open(snakemake.log[0], "w")
try:
    with tracked(snakemake):
        index = validate_index(Path(snakemake.input.index).parent, Limits(**snakemake.params.gate), open_files=False)
        # Across shards, from the sha256 each shard's job recorded: one recording in one group.
        check_one_recording(g for f in snakemake.input.shards for g in json.load(open(f))["groups"])
        counts = index.groupby(["evidence_set", "category"]).size()
        write_json(
            {"groups": len(index), "counts": {f"{a}/{b}": int(n) for (a, b), n in counts.items()}},
            snakemake.output[0],
        )
except RecordingError as e:
    print(f"error: {e}", file=sys.stderr)
    sys.exit(f"error: {e}")
