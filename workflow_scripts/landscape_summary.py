"""What the landscape allows: the per-target optimum against each architecture's policies, the optimum
regressed per section, and each architecture fitted to it: results/landscape/{summary.json,architectures.csv}."""

import json
import sys

import pandas as pd
import torch

from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.paper import html
from embodied_snap.policy import landscape, search, simulate

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    P, I = snakemake.params, snakemake.input
    sim, ws = simulate.for_job(I, P)
    opt = read_parquet(I.optimum)
    ev = read_parquet(I.evaluation)
    T = search.Targets(ev[ev.target_id.isin(opt.target_id)].set_index("target_id").loc[opt.target_id].reset_index(), ws)
    evals = pd.concat([read_parquet(f) for f in [*I.benchmark_evals, I.fixed]], ignore_index=True)
    s, table = landscape.summarize(sim, opt, T, evals, P.policy["ranges"], P.seed)
    print(json.dumps(s["sections"]["common_vs_distinct"]), file=sys.stderr)
    print(table.to_string(), file=sys.stderr)
    with open(snakemake.output.summary, "w") as f:
        json.dump(s, f, indent=1)
    table.to_csv(snakemake.output.table, index=False, lineterminator="\n")
    with open(snakemake.output.html, "w") as f:
        f.write(html.table("What the landscape allows", "docs/policy.md, Landscape.", list(table.columns),
                           table.round(4).to_dict("records")))
