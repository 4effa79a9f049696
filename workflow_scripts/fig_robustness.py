"""Fig. S1: the architecture result on the benchmark and its robustness variants."""

import json
import sys

from embodied_snap.figures.robustness import plot_robustness
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    plot_robustness(json.load(open(snakemake.input.summary)), snakemake.output.pdf, snakemake.output.png)
