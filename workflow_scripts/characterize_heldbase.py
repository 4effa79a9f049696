"""Held-base trials: causal detectors against the event (the snap; the hand's push for comparison)."""

import json
import sys

from embodied_snap.characterize import heldbase, load
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.sources import recordings

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    p = snakemake.params
    servo_fit = json.load(open(snakemake.input.servo))
    proto = from_params(p.protocol)
    gap = proto.sampling.max_gap_s  # mocap dropouts bridged
    d = p.detectors  # config characterize.heldbase: thresholds and window_s
    snap = proto.thresholds.attach_speed_mps  # the snap: the snap_speed_event label's rule
    tr = [dict(group_id=g, **heldbase.trial(*load.group(p.raw, g), servo_fit, d, gap, snap)) for g in p.groups]
    out = dict(heldbase.summarize(tr, d["window_s"]), recordings=recordings(p.groups, p.groups))
    print({k: v for k, v in out.items() if k != "trials"}, file=sys.stderr)
    write_json(out, snakemake.output[0])
