"""The claims ledger (results/tables/claims.{csv,md}) and the report's captions."""

import sys
from pathlib import Path

from embodied_snap.lineage.records import tracked
from embodied_snap.paper import captions, ledger

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    i, o = snakemake.input, snakemake.output
    rows = ledger.ledger(list(i.claims), ".", snakemake.params.simulated)
    ledger.write(rows, o.csv, o.md, o.html)
    captions.write_figure_captions(list(i.figs), "report", Path(o.caption).parent, rows, ".")
    Path(o.caption).write_text(
        "**The claims ledger**: every paper number beside ours, from every stage's claims table "
        f"(results/<stage>/claims.csv). {ledger.count_line(rows)}. Agreement: inside the paper's interval, "
        "or within the relative tolerance of reference/paper_values.yaml (``agreement``) of a point value; "
        "*by construction* where the simulated rig took one of its inputs from that result (docs/twin.md).\n"
    )
    print(ledger.count_line(rows), file=sys.stderr)
