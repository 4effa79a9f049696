"""Figure 1: the arm, the primitive on a recorded strike, the shared policy's commands."""

import json
import sys
from pathlib import Path

from embodied_snap.characterize.load import group
from embodied_snap.figures.system import RecordedStrike, plot_system
from embodied_snap.io import read_parquet
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    i = snakemake.input
    mocap, servo, meta = group(snakemake.params.raw, snakemake.params.group)
    selected = json.load(open(i.summary))["selected"]
    ev = read_parquet(next(f for f in i.evals if Path(f).stem == f"shared_seed{selected['seed']}"))
    # the render's path, or an empty list with a real rig
    render = str(i.render) if isinstance(i.render, str) else None
    strike = RecordedStrike(mocap=mocap, servo=servo, meta=meta)
    shown = plot_system(render, strike, selected, ev, snakemake.output.pdf, snakemake.output.png,
                        max_gap_s=from_params(snakemake.params.protocol).sampling.max_gap_s)
    print(json.dumps(shown, indent=1), file=sys.stderr)
