"""Delay sweep (held out from every fit): speed and approach over tau, attach counts, the
supported timing interval."""

import sys

from embodied_snap.characterize import delay, trials
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    ee = from_params(snakemake.params.protocol).rig.end_effector_m  # the cup face
    out = delay.summarize(trials.table(snakemake.params.raw, snakemake.params.groups, ee,
                         from_params(snakemake.params.protocol).sampling.max_gap_s))
    print({k: v for k, v in out.items() if k != "trials"}, file=sys.stderr)
    write_json(out, snakemake.output[0])
