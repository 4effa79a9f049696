"""CMA-ES runs (paper IV-B/IV-C): one architecture and optimisation seed, or such a run continued to a
larger budget (input `resume`: the run and its CMA-ES state); or several runs in lockstep (config
policy.batch_runs), each generation of all of them one batch of rollouts. Params `runs`: the
(architecture, seed) of each output, in order."""

import json
import sys

import torch

from embodied_snap.io import read_parquet, write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search, simulate

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.for_job(I, P)
    tr = read_parquet(I.training)
    train = search.Targets(tr, ws)
    resume = None
    if "resume" in I.keys():
        resume = dict(json.load(open(I.resume)), state=open(I.resume_state, "rb").read())
    O = snakemake.output  # one run and state, or (lockstep) the lists of params runs, in order
    outputs = list(zip(*([o] if isinstance(o, str) else o for o in (O.run, O.state))))
    targets = search.SearchTargets(train=train, gen_of=tr["generation"].to_numpy(),
                                   select=search.Targets(read_parquet(I.selection), ws),
                                   norm=search.feature_stats(train))
    spec = search.SearchSpec(ranges=P.policy["ranges"], generations=P.generations, popsize=P.popsize,
                             start=P.start, snapshots=P.snapshots)
    done = search.lockstep(sim, [(a, s, resume) for a, s in P.runs], targets, spec)
    for run, (run_path, state_path) in zip(done, outputs):
        c = run["curve"]
        print(f"{run['arch']} seed {run['seed']}: held-out {c[0]['heldout_reward']:.3f} -> "
              f"{c[-1]['heldout_reward']:.3f}, selected generation {run['selected_generation']} "
              f"({run['selection_reward']:.3f})", file=sys.stderr)
        with open(state_path, "wb") as f:  # already pickled by search.lockstep
            f.write(run.pop("state"))
        write_json(run, run_path)
