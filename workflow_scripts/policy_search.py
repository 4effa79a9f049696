"""One CMA-ES run: an architecture and an optimisation seed (paper IV-B/IV-C); or such a run continued
to a larger budget (input `resume`: the run and its CMA-ES state)."""

from embodied_snap.lineage import records  # noqa: F401 -- first, so every read of the job is watched

# isort: split

import json
import sys

import torch

from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search, simulate
from embodied_snap.rawformat import write_json

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
    norm = resume["norm"] if resume else search.feature_stats(train)
    run = search.cmaes(sim, P.arch, P.seed, train, tr["generation"].to_numpy(),
                       search.Targets(read_parquet(I.selection), ws), norm,
                       P.policy["ranges"], P.generations, P.popsize, P.start,
                       snapshots=P.snapshots, resume=resume)
    c = run["curve"]
    print(f"{P.arch} seed {P.seed}: held-out {c[0]['heldout_reward']:.3f} -> {c[-1]['heldout_reward']:.3f}, "
          f"selected generation {run['selected_generation']} ({run['selection_reward']:.3f})", file=sys.stderr)
    with open(snakemake.output.state, "wb") as f:  # already pickled by cmaes
        f.write(run.pop("state"))
    write_json(run, snakemake.output.run)
