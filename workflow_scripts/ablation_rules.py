"""Every release rule and the two references on the release-evaluation targets (never read by the
offset fit): one row per rule and target."""

import json
import sys

import torch

from embodied_snap.ablation import release
from embodied_snap.ablation.rollouts import rule_clock, selected_actions
from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search, simulate

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.for_job(I, P)
    offsets = json.load(open(I.offsets))["rules"]
    T = search.Targets(read_parquet(I.release), ws)
    run, act = selected_actions(I.runs, T, P.policy["ranges"])
    proto = rule_clock(sim, P.triggers, ws["hanging_axis"])
    t_e = release.events(sim, act, T, proto)
    steps, tab = release.table(sim, act, T, proto)
    df = release.compare(T, steps, tab, release.release_times(act["tau"], t_e, offsets, P.clock_s), proto)
    print(df.groupby("rule")[["reward", "miss_m", "at_bound"]].mean(), file=sys.stderr)
    df.to_parquet(snakemake.output[0], index=False)
