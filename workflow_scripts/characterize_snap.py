"""Snap classifier P_snap(rho1, rho2) from the training-split characterisation groups; the JSON
is what the policy reward loads (embodied_snap.characterize.snap.load)."""

import sys

from embodied_snap.characterize import snap, trials
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    ee = from_params(snakemake.params.protocol).rig.end_effector_m  # the cup face
    v = from_params(snakemake.params.protocol).thresholds.attach_speed_mps
    out = snap.fit(trials.table(snakemake.params.raw, snakemake.params.groups, ee,
                         from_params(snakemake.params.protocol).sampling.max_gap_s), v)
    print({k: v for k, v in out.items() if k not in ("trials", "grid")}, file=sys.stderr)
    write_json(out, snakemake.output[0])
