"""Figure 2: actuation limits and attachment evidence."""

import json
import sys

from embodied_snap.figures.limits import plot_limits
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    i = snakemake.input
    plot_limits(json.load(open(i.servo)), json.load(open(i.release)), json.load(open(i.attachment)),
                snakemake.output.pdf, snakemake.output.png, snakemake.params.seed,
                attach_speed_mps=from_params(snakemake.params.protocol).thresholds.attach_speed_mps)
