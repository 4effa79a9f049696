"""The benchmark and its robustness variants side by side: results/robustness/summary.json."""

import json
import sys

import pandas as pd

from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.policy.analysis import SummaryCriteria
from embodied_snap.policy.robustness import BENCHMARK, VariantBudgets, summarize_variants
from embodied_snap.protocol import from_params


def evals(files):
    return pd.concat([read_parquet(f) for f in files], ignore_index=True)


def runs(files):
    return [json.load(open(f)) for f in files]


sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    i, p = snakemake.input, snakemake.params
    bench = runs(i.benchmark_runs)
    runs_of = {BENCHMARK: bench, "uniform": runs(i.uniform_runs)}
    for v in p.variants:
        if v != "uniform" and p.budget_generations[v] > p.generations:
            runs_of[v] = runs(f for f in i.longer_runs if f"/{v}/" in f)
    evals_of = {BENCHMARK: evals(i.benchmark_evals)}
    evals_of.update({v: evals(f for f in i.evals if f"/{v}/eval/" in f) for v in p.variants})
    fixed = read_parquet(i.benchmark_fixed)
    fixed_of = {v: fixed for v in evals_of} | {"uniform": read_parquet(i.uniform_fixed)}
    budgets = VariantBudgets(generations=p.generations, budget_generations=p.budget_generations,
                             evaluations_per_generation=p.evaluations_per_generation)
    criteria = SummaryCriteria(tolerances=p.tolerances, d_f=p.d_f, v_min=p.v_min,
                               timing_s=from_params(p.protocol).primitive.timing_s)
    s = summarize_variants(bench, runs_of, evals_of, fixed_of, budgets, criteria)
    for v, x in s.items():
        print(v, x["generations"], x["ranking_reward"], x["ranking_attachment"], file=sys.stderr)
    with open(snakemake.output[0], "w") as f:
        json.dump(s, f, indent=1)
