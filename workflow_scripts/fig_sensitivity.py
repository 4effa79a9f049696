"""Fig. S2: the architecture result from each start, and how tied the shared sections are."""

import json
import sys

from embodied_snap.figures.sensitivity import plot_sensitivity
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    plot_sensitivity(json.load(open(snakemake.input.summary)), snakemake.output.pdf, snakemake.output.png)
