"""Prove docs/design.md section 3 on the DAG and on the records; fail the workflow on any leak.
Missing records are not reported here (jobs beside this one may be rebuilding theirs right now);
`esnap check-separation` after the run does."""

from embodied_snap.lineage import records  # noqa: F401 -- first, so every read of the job is watched

# isort: split

import sys

from embodied_snap.lineage.checks import check
from embodied_snap.lineage.records import tracked
from embodied_snap.rawformat import write_json

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    result = check(".", config_overrides=snakemake.params.config, complete=False)
    for v in result["violations"]:
        print(f"leak: {v}", file=sys.stderr)
    if not result["ok"]:
        sys.exit(
            f"separation violated: {result['violations'][0]} "
            f"(+{len(result['violations']) - 1} more, see {snakemake.log[0]})"
        )
    write_json(result, snakemake.output[0])
