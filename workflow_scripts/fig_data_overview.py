"""Figure 0: the recordings at a glance."""

import json
import sys

from embodied_snap.figures.overview import plot_overview
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    plot_overview(json.load(open(snakemake.input.manifest)), snakemake.output.pdf, snakemake.output.png)
