"""Delay-sweep gate: measured vs predicted peak tip speed and travel, per seed."""

import sys

import torch

from embodied_snap.dynamics import data, gate
from embodied_snap.dynamics.model import load
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(1)
    models = {str(s): load(p) for s, p in zip(snakemake.params.seeds, snakemake.input.models)}
    out = gate.sweep(models, data.frames(snakemake.input.shards), data.metas(snakemake.input.metas),
                     snakemake.params.after_s1, from_params(snakemake.params.protocol))
    print({k: v for k, v in out.items() if k not in ("trials", "per_tau")}, file=sys.stderr)
    write_json(out, snakemake.output[0])
