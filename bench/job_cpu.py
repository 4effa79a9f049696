"""CPU seconds per job of a finished run, per stage, from its jobs' `benchmark:` files.

    python bench/job_cpu.py [BENCHMARKS_DIR]      # default: benchmarks/

A stage is the first folder under BENCHMARKS_DIR (a file directly in it is its own stage). Prints,
per stage: jobs, CPU-s in all (Snakemake's `cpu_time`: user + system of the job's processes), CPU-s
per job (mean and median), wall seconds per job and the job's mean CPU use in % of one core
(Snakemake's `mean_load`). Used to put the lineage watch's cost (docs/benchmarks.md, "The watch
from the start") beside a job's whole cost.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd


def table(bench: Path) -> pd.DataFrame:
    rows = []
    for f in sorted(bench.rglob("*.tsv")):
        rel = f.relative_to(bench)
        stage = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        b = pd.read_csv(f, sep="\t")
        rows += [dict(stage=stage, cpu_s=r.cpu_time, wall_s=r.s, load=r.mean_load) for r in b.itertuples()]
    df = pd.DataFrame(rows)
    g = df.groupby("stage")
    return pd.DataFrame({
        "jobs": g.size(),
        "cpu_s": g.cpu_s.sum().round(1),
        "cpu_s_per_job": g.cpu_s.mean().round(2),
        "median": g.cpu_s.median().round(2),
        "wall_s_per_job": g.wall_s.mean().round(1),
        "cpu_pct": g.load.mean().round(0),
    })


if __name__ == "__main__":
    print(table(Path(sys.argv[1] if len(sys.argv) > 1 else "benchmarks")).to_string())
