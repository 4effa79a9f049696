"""Release modes: peak tip speeds, direct range, instantaneous fraction above 1 m/s, rates at the
operating point over the Eq. 2 ceilings."""

import json
import sys

from embodied_snap.characterize import release, trials
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    ee = from_params(snakemake.params.protocol).rig.end_effector_m  # the cup face
    rows = trials.table(snakemake.params.raw, snakemake.params.groups, ee,
                         from_params(snakemake.params.protocol).sampling.max_gap_s)
    v = from_params(snakemake.params.protocol).thresholds.attach_speed_mps
    out = release.summarize(rows, json.load(open(snakemake.input.servo))["ceiling_rad_s"], v)
    print({k: v for k, v in out.items() if k != "speeds"}, file=sys.stderr)
    write_json(out, snakemake.output[0])
