"""Figure 6: release-rule ablation in simulation."""

import json
import sys

from embodied_snap.figures.ablation import plot_ablation
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    plot_ablation(json.load(open(snakemake.input.summary)), snakemake.output.pdf, snakemake.output.png)
