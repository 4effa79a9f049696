"""The run as a Workflow Run RO-Crate: results/crate/ro-crate-metadata.json."""

import sys
from pathlib import Path

from embodied_snap.lineage.records import tracked
from embodied_snap.paper.crate import write

sys.stderr = open(snakemake.log[0], "w")
# The crate hashes only what it declares (files, or files under a declared folder).
DECLARED = [str(f).rstrip("/") for f in snakemake.input]


def declared(path: str) -> bool:
    return any(path == d or path.startswith(d + "/") for d in DECLARED)


with tracked(snakemake):
    print(write(".", str(Path(snakemake.output[0]).parent), may_read=declared), file=sys.stderr)
