"""Architecture benchmark and generalisation (V-A, V-B): results/policy/summary.json."""

import json
import sys

import pandas as pd

from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.policy.analysis import SummaryCriteria, summarize
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    i, p = snakemake.input, snakemake.params
    runs = [json.load(open(f)) for f in i.runs]
    evals = pd.concat([read_parquet(f) for f in i.evals if f != i.fixed], ignore_index=True)
    criteria = SummaryCriteria(tolerances=p.tolerances, d_f=p.d_f, v_min=p.v_min,
                               timing_s=from_params(p.protocol).primitive.timing_s)
    s = summarize(runs, evals, read_parquet(i.fixed), p.budget_evaluations, criteria)
    print(json.dumps({k: s[k] for k in ("archs", "seeds", "reward", "reach")}, indent=1), file=sys.stderr)
    with open(snakemake.output[0], "w") as f:
        json.dump(s, f, indent=1)
