"""Assemble results/figures/ from the per-figure jobs. Each copy gets its own record, so an audit of
one figure follows that figure's job alone, not every figure's."""

import shutil
import sys
from datetime import datetime, timezone
from pathlib import Path

from embodied_snap.lineage.records import write_record

sys.stderr = open(snakemake.log[0], "w")
started = datetime.now(timezone.utc).isoformat()
out = Path(snakemake.output[0])
out.mkdir(parents=True, exist_ok=True)
for src in snakemake.input.figs:
    dst = out / Path(src).name
    shutil.copyfile(src, dst)
    write_record(
        "figures",
        {"figure": dst.name},
        inputs=[src, snakemake.input.separation],
        outputs=[str(dst)],
        params={},
        started=started,
    )
    print(f"{src} -> {dst}", file=sys.stderr)
