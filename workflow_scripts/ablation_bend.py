"""Bend-point propagation: the selected policy's simulated successes on the evaluation targets and
the simulated rig's recorded strikes (training groups), by the same estimate."""

import sys

import numpy as np
import pandas as pd
import torch

from embodied_snap.ablation import bend, kinematics
from embodied_snap.ablation.rollouts import rollout, selected_actions
from embodied_snap.dynamics import data
from embodied_snap.io import read_parquet, write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search, simulate
from embodied_snap.policy.analysis import REPORT_TOL_M
from embodied_snap.policy.reward import attached

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.for_job(I, P)
    n = np.asarray(ws["hanging_axis"])
    T = search.Targets(read_parquet(I.evaluation), ws)
    run, act = selected_actions(I.runs, T, P.policy["ranges"])
    out = rollout(sim, act, T.p, T.normal, states=True)
    R = P.policy["reward"]
    ok = attached(out["lateral_m"], out["gap_m"], out["v_pk_mps"], REPORT_TOL_M, R["d_f_m"], R["v_min_sim_mps"])
    corr = bend.window_correlations(out["x"][ok], out["k_s1"][ok], n, sim.dt)
    rig = bend.recorded(data.frames(I.shards, P.groups), data.metas(I.metas), n, P.after_s1, sim.dt)
    res = {"seed": run["seed"], "n_targets": len(T), "model": kinematics.travel_stats(corr),
           "rig": kinematics.travel_stats(rig), "model_correlations": corr.tolist(), "rig_correlations": rig.tolist()}
    print({k: res[k] for k in ("model", "rig")}, file=sys.stderr)
    write_json(res, snakemake.output.bend)
    pd.DataFrame({"target_id": T.df["target_id"], **{k: out[k] for k in ("lateral_m", "gap_m", "miss_m", "v_pk_mps",
                                                                          "reward")}}).to_parquet(
        snakemake.output.outcomes, index=False)
