"""Record one shard of acquisition groups on the simulated rig (thin adapter).

Recordings are source data: written read-only, like Snakemake's protected outputs."""

import os
import sys
from pathlib import Path

import pandas as pd

from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.twin.acquire import acquire_groups

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    p = snakemake.params
    rows = acquire_groups(
        pd.DataFrame(p.groups), p.raw, seed=p.seed, proto=from_params(p.protocol), dt=p.dt, hold=p.hold
    )
    for f in snakemake.output.recordings:
        os.chmod(f, 0o444)
    # the shard names its record (results/twin/acquired/<shard>.json)
    write_json({"shard": Path(snakemake.output.acquired).stem, "groups": rows}, snakemake.output.acquired)
