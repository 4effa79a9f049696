"""Persistence baseline on the validation windows (h = 1..35)."""

import sys

from embodied_snap.dynamics import evaluate as E
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.windows import load_windows

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    proto = from_params(snakemake.params.protocol)
    dt, arm = proto.sampling.dt, proto.rig.arm_length_m
    W = load_windows(snakemake.input.validation)
    h = E.eval_horizon(dt)
    idx = E.eligible(W, h)
    out = dict(E.summary(E.persistence_tip_mm(W, idx, h), dt, arm), recordings=E.recordings_of(W, idx))
    print(out["at_s_mm"], file=sys.stderr)
    write_json(out, snakemake.output[0])
