"""Figure 4: hardware gates for controller development."""

import json
import sys

from embodied_snap.figures.gates import plot_gates
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    i = snakemake.input
    proto = from_params(snakemake.params.protocol)
    plot_gates(json.load(open(i.persistence)), [json.load(open(p)) for p in i.validation],
               json.load(open(i.gate)), proto.sampling.dt, proto.windows.horizon,
               snakemake.output.pdf, snakemake.output.png)
