"""What the simulated rig shows (issue 2 table), computed from its recordings."""

import sys

import pandas as pd

from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.twin.phenomena import phenomena

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    p = snakemake.params
    write_json(phenomena(p.raw, pd.DataFrame(p.groups), from_params(p.protocol)), snakemake.output[0])
