"""Twin phenomena beside the paper's hardware values and the twin's acceptance ranges."""

import json
import sys

from embodied_snap.provenance import tracked
from embodied_snap.rawformat import write_json
from embodied_snap.reference import twin_comparison

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    ph = json.load(open(snakemake.input.phenomena))
    truth = json.load(open(snakemake.input.truth))
    rows = twin_comparison(ph)
    for r in rows:
        print(f"{r['key']:40s} paper {r['paper']!s:18s} twin {r['ours']!s:28s} {'ok' if r['ok'] else 'OUT OF RANGE'}", file=sys.stderr)
    write_json({"phenomena": rows, "all_ok": all(r["ok"] for r in rows), "truth": truth}, snakemake.output[0])
