"""The benchmark from each start, read by the fixed rule, with the slope probe: results/sensitivity/summary.json."""

import json
import sys

import pandas as pd

from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.policy import search
from embodied_snap.policy.analysis import SummaryCriteria
from embodied_snap.policy.sensitivity import ProbeSpec, summarize_starts
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    i, p = snakemake.input, snakemake.params
    bench = next(iter(p.starts))
    runs_of = {s: [] for s in p.starts}
    evals_of = {s: [] for s in p.starts}
    for f in i.benchmark_runs:
        runs_of[bench].append(json.load(open(f)))
    evals_of[bench] = [read_parquet(f) for f in i.benchmark_evals]
    for f in i.runs:
        runs_of[f.split("/")[-3]].append(json.load(open(f)))
    for f in i.evals:
        evals_of[f.split("/")[-3]].append(read_parquet(f))
    evals_of = {s: pd.concat(v, ignore_index=True) for s, v in evals_of.items()}
    T = search.Targets(read_parquet(i.evaluation), json.load(open(i.workspace)))
    criteria = SummaryCriteria(tolerances=p.tolerances, d_f=p.d_f, v_min=p.v_min,
                               timing_s=from_params(p.protocol).primitive.timing_s)
    s = summarize_starts(p.starts, runs_of, evals_of, read_parquet(i.fixed), p.budget_evaluations, criteria,
                         ProbeSpec(features=T.g, seed=p.seed))
    for name, x in s.items():
        print(name, {a: round(r["mean"], 4) for a, r in x["reward"].items()}, "reproduced:", x["reproduced"],
              file=sys.stderr)
    with open(snakemake.output[0], "w") as f:
        json.dump(s, f, indent=1)
