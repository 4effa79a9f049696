"""Figure 5: architecture benchmark under a common simulation protocol."""

import json
import sys

from embodied_snap.figures.benchmark import plot_benchmark
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    plot_benchmark(json.load(open(snakemake.input.summary)), snakemake.output.pdf, snakemake.output.png)
