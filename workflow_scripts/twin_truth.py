"""The simulated rig's true parameters; only the twin validation report may read them."""

import sys

from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.twin.truth import truth

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    write_json(truth(snakemake.params.seed, snakemake.params.sessions), snakemake.output[0])
