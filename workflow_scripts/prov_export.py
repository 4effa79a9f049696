"""Export the run's provenance as W3C PROV-JSON."""

import sys

from embodied_snap.lineage.prov import export
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    export(".", snakemake.output[0], raw=snakemake.params.raw)
