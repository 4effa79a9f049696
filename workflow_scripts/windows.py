"""Windows of one split from that split's resampled shards only."""

import sys

import pandas as pd

from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.windows import make_windows, save_windows

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    frames = pd.concat([read_parquet(f) for f in snakemake.input.shards], ignore_index=True)
    arrays = make_windows(frames, from_params(snakemake.params.protocol).windows)
    save_windows(snakemake.output[0], arrays)
    n = len(arrays["anchors"])
    print(f"{snakemake.wildcards.role}: {len(arrays['group_ids'])} groups, {n} windows, "
          f"{int(arrays['snap'].sum())} snap, {int(arrays['fast'].sum())} fast", file=sys.stderr)
