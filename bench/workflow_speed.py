"""Benchmark the workflow's bookkeeping on an existing run: DAG build (`snakemake -n`) and `esnap audit`.

Usage (after a run on the budget to measure):  python bench/workflow_speed.py --budget paper
Prints seconds per call (median of --repeat runs) and the number of groups and jobs involved.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

BIN = Path(sys.executable).parent


def timed(cmd: list[str], repeat: int) -> tuple[float, subprocess.CompletedProcess]:
    times, r = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), r


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--budget", default="paper")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--audit", default="results/figures/fig0_data_overview.pdf")
    a = ap.parse_args()
    n_groups = len(pd.read_csv("raw_data/index.csv"))
    t, r = timed([str(BIN / "snakemake"), "-n", "results/figures", "--config", f"budget={a.budget}"], a.repeat)
    print(f"snakemake -n results/figures  budget={a.budget}  groups={n_groups}  {t:.2f} s  (rc {r.returncode})")
    t, r = timed([str(BIN / "snakemake"), "-n", "--forceall", "all", "--config", f"budget={a.budget}"], 1)
    jobs = sum(1 for line in r.stdout.splitlines() if line.startswith(("rule ", "checkpoint ")))
    print(f"snakemake -n --forceall all    jobs={jobs}  {t:.2f} s")
    t, r = timed([str(BIN / "esnap"), "audit", a.audit], a.repeat)
    print(f"esnap audit {a.audit}  {t:.2f} s  (rc {r.returncode})")


if __name__ == "__main__":
    main()
