"""Attachment: speed/tilt logistic model with session-grouped CV AUC, and the threshold counts."""

import sys

from embodied_snap.characterize import attachment, trials
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.rawformat import RecordingError

sys.stderr = open(snakemake.log[0], "w")
try:
    with tracked(snakemake):
        ee = from_params(snakemake.params.protocol).rig.end_effector_m  # the cup face
        v = from_params(snakemake.params.protocol).thresholds.attach_speed_mps
        out = attachment.fit(trials.table(snakemake.params.raw, snakemake.params.groups, ee,
                         from_params(snakemake.params.protocol).sampling.max_gap_s), v)
        print({k: v for k, v in out.items() if k != "trials"}, file=sys.stderr)
        write_json(out, snakemake.output[0])
except RecordingError as e:  # a group the gate should have stopped: one line, never a dropped trial
    print(f"error: {e}", file=sys.stderr)
    sys.exit(f"error: {e}")
