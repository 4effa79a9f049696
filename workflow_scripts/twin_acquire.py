"""Record one shard of acquisition groups on the simulated rig (thin adapter)."""

import sys

import pandas as pd

from embodied_snap.provenance import tracked
from embodied_snap.rawformat import write_json
from embodied_snap.twin.acquire import acquire_groups

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    p = snakemake.params
    rows = acquire_groups(pd.DataFrame(p.groups), p.raw, seed=p.seed, dt=p.dt)
    write_json({"shard": snakemake.wildcards.shard, "groups": rows}, snakemake.output[0])
