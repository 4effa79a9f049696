"""The deployment trials on the simulated rig: each through the virtual Dynamixel bus with
`esnap deploy`'s client, two at a time. Complete trials that pass the gate enter the deployment
index; aborted ones are listed with their cause and never enter it."""

import sys
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path

from embodied_snap import rawformat as RF
from embodied_snap.lineage.records import tracked
from embodied_snap.rawformat import RecordingError
from embodied_snap.twin.deployment import run_trial
from embodied_snap.validate import Limits, validate_group

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    P = snakemake.params
    raw = Path(snakemake.output.index).parent
    n_pl, per = P.placements, P.trials_per_placement
    plan = [((k - 1) % n_pl + 1, k) for k in range(1, n_pl * per + 1)]  # placements interleaved over the session
    job = partial(run_trial, snakemake.input.manifest, raw=raw, seed=P.seed, n_sessions=P.sessions, dt=P.dt,
                  speed_mps=P.speed_mps)
    with ProcessPoolExecutor(snakemake.threads) as pool:
        results = list(pool.map(job, [p for p, _ in plan], [k for _, k in plan]))
    rows, aborted = [], []
    lim = Limits.from_config(snakemake.config)
    for r in results:
        if "cause" in r:
            aborted.append(r)
            continue
        try:
            validate_group(raw, r["group_id"], r, lim)  # the gate of docs/data.md, as for every recording
        except RecordingError as e:  # kept out of the index with its reason, like an aborted trial
            aborted.append(dict(group_id=r["group_id"], cause=f"rejected by the gate: {e}"))
            continue
        rows.append(r)
        print(f"{r['group_id']}: recorded", file=sys.stderr)
    for a in aborted:
        print(f"{a['group_id']}: {a['cause']}", file=sys.stderr)
    RF.write_json(dict(planned=len(plan), recorded=len(rows), aborted=aborted), snakemake.output.aborted)
    RF.write_index(rows, snakemake.output.index)
