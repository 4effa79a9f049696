"""Prove docs/design.md section 3 on the records, beside the DAG's proof (check_separation_dag);
fail the workflow on any leak.
Missing records are not reported here (jobs beside this one may be rebuilding theirs right now);
`esnap check-separation` after the run does."""

import json
import sys

from embodied_snap.io import write_json
from embodied_snap.lineage.checks import check
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    with open(snakemake.input.dag) as f:
        dag = json.load(f)
    result = check(".", config_overrides=snakemake.params.config, complete=False, dag=dag)
    for v in result["violations"]:
        print(f"leak: {v}", file=sys.stderr)
    if not result["ok"]:
        sys.exit(
            f"separation violated: {result['violations'][0]} "
            f"(+{len(result['violations']) - 1} more, see {snakemake.log[0]})"
        )
    write_json(result, snakemake.output[0])
