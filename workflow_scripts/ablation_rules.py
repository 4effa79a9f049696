"""Every release rule and the two references on the release-evaluation targets (never read by the
offset fit): one row per rule and target."""

import json
import sys

import numpy as np
import torch

from embodied_snap.ablation import release
from embodied_snap.ablation.rollouts import rule_clock, selected_run
from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search, simulate
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.from_files(I.models, I.bank, I.snap, I.workspace, P.policy, P.after_s1, P.ee_m,
                                  from_params(P.protocol))
    run = selected_run([json.load(open(f)) for f in I.runs])
    offsets = json.load(open(I.offsets))["rules"]
    T = search.Targets(read_parquet(I.release), ws)
    act = search.policy_actions("shared", np.asarray(run["theta"]), T, run["norm"], P.policy["ranges"])
    proto = rule_clock(sim, P.triggers, ws["hanging_axis"])
    t_e = release.events(sim, act, T, proto)
    steps, tab = release.table(sim, act, T, proto)
    df = release.compare(T, steps, tab, release.release_times(act["tau"], t_e, offsets, P.clock_s), proto)
    print(df.groupby("rule")[["reward", "miss_m", "at_bound"]].mean(), file=sys.stderr)
    df.to_parquet(snakemake.output[0], index=False)
