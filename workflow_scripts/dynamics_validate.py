"""Validation tip error of one selected seed; the gap between carried-state and re-encoded rollouts."""

import sys

import torch

from embodied_snap.dynamics import evaluate as E
from embodied_snap.dynamics.model import load
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.windows import load_windows

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    model = load(snakemake.input.model)
    W = load_windows(snakemake.input.validation)
    proto = from_params(snakemake.params.protocol)
    dt, arm = proto.sampling.dt, proto.rig.arm_length_m
    h = E.eval_horizon(dt)
    idx = E.eligible(W, h)
    out = E.summary(E.model_tip_mm(model, W, idx, h), dt, arm)
    out["carry_gap"] = E.carry_gap(model, W, idx)
    out["recordings"] = E.recordings_of(W, idx)
    print(out["at_s_mm"], out["carry_gap"], file=sys.stderr)
    write_json(out, snakemake.output[0])
