"""One shard of groups on the 50 Hz grid, each group on its own."""

import sys

from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.resample import resample_shard
from embodied_snap.validate import RecordingError

sys.stderr = open(snakemake.log[0], "w")
p = snakemake.params
grid = from_params(p.protocol).sampling
try:
    with tracked(snakemake):
        df = resample_shard(p.raw, p.groups, grid.hz, grid.max_gap_s)
        df.to_parquet(snakemake.output[0], index=False, compression="zstd")
except RecordingError as e:
    print(f"error: {e}", file=sys.stderr)
    sys.exit(f"error: {e}")
