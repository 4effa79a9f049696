"""Figure 3: snap preconditions and timing."""

import json
import sys

from embodied_snap.figures.snap import plot_snap
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    i = snakemake.input
    plot_snap(json.load(open(i.snap)), json.load(open(i.delay_sweep)), snakemake.output.pdf, snakemake.output.png,
              attach_speed_mps=from_params(snakemake.params.protocol).thresholds.attach_speed_mps)
