"""Strike cloud, Delta_str and directional workspace of the training-split dynamics groups."""

import sys

import numpy as np

from embodied_snap.dynamics import data
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import targets
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    with np.load(snakemake.input.bank) as z:
        n = z["n"]
    ws = targets.workspace(data.frames(snakemake.input.shards, snakemake.params.groups),
                           data.metas(snakemake.input.metas), n, snakemake.params.after_s1, snakemake.params.ee_m,
                           from_params(snakemake.params.protocol).primitive.phi0_deg)
    print({k: v for k, v in ws.items() if not k.startswith("strike")}, file=sys.stderr)
    write_json(ws, snakemake.output[0])
