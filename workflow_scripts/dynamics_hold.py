"""Hold bank of the training-split dynamics groups and its leave-one-session-out errors."""

import sys

from embodied_snap.dynamics import data, hold
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.sources import recordings
from embodied_snap.windows import save_windows

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    proto = from_params(snakemake.params.protocol)
    B = hold.bank(data.frames(snakemake.input.shards, snakemake.params.groups), data.metas(snakemake.input.metas),
                  proto.primitive.phi0_deg, proto.windows.history)
    out = hold.leave_one_session_out(B, proto.rig.arm_length_m)
    out["recordings"] = recordings(snakemake.params.groups, B["group_ids"].tolist(), "no hold in its record")
    print(out, file=sys.stderr)
    save_windows(snakemake.output.bank, B)  # the same byte-stable .npz writer as the windows
    write_json(out, snakemake.output.summary)
