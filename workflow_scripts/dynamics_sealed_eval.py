"""The single sealed evaluation: each selected seed and persistence, once, on every sealed window."""

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
    W = load_windows(snakemake.input.sealed)
    proto = from_params(snakemake.params.protocol)
    dt, arm = proto.sampling.dt, proto.rig.arm_length_m
    h = E.eval_horizon(dt)
    idx = E.eligible(W, h)
    out = {"n_windows_all": int(len(W["anchors"])), "n_groups": int(len(W["group_ids"])),
           "persistence": E.summary(E.persistence_tip_mm(W, idx, h), dt, arm), "seeds": {},
           "recordings": E.recordings_of(W, idx)}
    for seed, path in zip(snakemake.params.seeds, snakemake.input.models):
        out["seeds"][str(seed)] = E.summary(E.model_tip_mm(load(path), W, idx, h), dt, arm)
        print(seed, out["seeds"][str(seed)]["at_s_mm"], file=sys.stderr)
    write_json(out, snakemake.output[0])
