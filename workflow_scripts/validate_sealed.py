"""Record the sealed test set the first time the dynamics corpus is split (embodied_snap/sealed.py)."""

import sys

import pandas as pd

from embodied_snap import sealed
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    groups = sealed.seal(snakemake.params.raw, pd.DataFrame(snakemake.params.plan), "first split")
    print(f"sealed set: {len(groups)} groups: {', '.join(groups)}", file=sys.stderr)
