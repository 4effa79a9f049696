"""The deployment trials on the simulated rig: each through the virtual Dynamixel bus with
`esnap deploy`'s client, config twin.trials_at_a_time side by side. Complete trials that pass the
gate enter the deployment index; aborted ones are listed with their cause and never enter it
(deploy.trials, as for the lab's trials)."""

import sys
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path

from embodied_snap.deploy import trials as T
from embodied_snap.lineage.records import tracked
from embodied_snap.twin.deployment import DeploymentSetup, run_trial
from embodied_snap.validate import Limits

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    P, O = snakemake.params, snakemake.output
    raw = Path(O.index).parent
    n_pl, per = P.placements, P.trials_per_placement
    plan = [((k - 1) % n_pl + 1, k) for k in range(1, n_pl * per + 1)]  # placements interleaved over the session
    setup = DeploymentSetup(raw=raw, seed=P.seed, n_sessions=P.sessions, dt=P.dt, speed_mps=P.speed_mps)
    job = partial(run_trial, snakemake.input.manifest, setup=setup)
    with ProcessPoolExecutor(P.at_a_time) as pool:
        results = list(pool.map(job, [p for p, _ in plan], [k for _, k in plan]))
    rows, aborted = T.gate(raw, results, Limits(**P.gate))
    for r in rows:
        print(f"{r['group_id']}: recorded", file=sys.stderr)
    for a in aborted:
        print(f"{a['group_id']}: {a['cause']}", file=sys.stderr)
    T.write(rows, aborted, len(plan), O.index, O.aborted)
