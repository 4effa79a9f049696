"""Prove docs/design.md section 3 on the Snakemake DAG (the half of the proof a changed recording
does not move); check_separation adds the records and fails the workflow on any leak."""

import sys

from embodied_snap.io import write_json
from embodied_snap.lineage.checks import static_proof
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    write_json(static_proof(".", config_overrides=snakemake.params.config), snakemake.output[0])
