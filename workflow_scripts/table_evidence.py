"""Table I from the lineage: results/tables/table1_evidence.{csv,md,tex} and its report caption."""

import json
import sys
from pathlib import Path

from embodied_snap.lineage.records import tracked
from embodied_snap.paper import table1

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    rows = table1.rows(json.load(open(snakemake.input.separation)), ".", simulated=snakemake.params.simulated)
    table1.write(rows, Path(snakemake.output.csv).with_suffix(""))
    print(Path(snakemake.output.md).read_text(), file=sys.stderr)
    proved = sum(r["verdict"].startswith("proved") for r in rows)
    Path(snakemake.output.caption).write_text(
        open(snakemake.input.static).read().rstrip()
        + f"\n\n**This run**: {len(rows)} rows, separation proved for {proved}, not proved for {len(rows) - proved}.\n"
    )
