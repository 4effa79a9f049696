"""Record one shard of acquisition groups on the simulated rig (thin adapter).

Recordings are source data: written read-only, like Snakemake's protected outputs."""

from embodied_snap.lineage import records  # noqa: F401 -- first, so every read of the job is watched

# isort: split

import os
import sys

import pandas as pd

from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.rawformat import group_paths, write_json
from embodied_snap.twin.acquire import acquire_groups

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake) as recordings:
    p = snakemake.params
    rows = acquire_groups(
        pd.DataFrame(p.groups), p.raw, seed=p.seed, proto=from_params(p.protocol), dt=p.dt, hold=p.hold
    )
    recordings += [str(f) for r in rows for f in group_paths(p.raw, r["group_id"]).values()]
    for f in recordings:
        os.chmod(f, 0o444)
    write_json({"shard": snakemake.wildcards.shard, "groups": rows}, snakemake.output[0])
