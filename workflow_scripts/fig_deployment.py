"""Fig. 7: a successful deployment trial, recorded (top) and as the dynamics model predicts it for
the same commands (bottom), rendered offscreen by MuJoCo."""

import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from embodied_snap.characterize import load  # noqa: E402
from embodied_snap.figures import deployment as F  # noqa: E402
from embodied_snap.lineage.records import tracked  # noqa: E402
from embodied_snap.policy.simulate import for_job  # noqa: E402
from embodied_snap.protocol import from_params  # noqa: E402

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    I, P = snakemake.input, snakemake.params
    trials = pd.read_csv(I.trials)
    if trials.empty:  # every trial aborted or was rejected: say so in the figure, do not invent one
        F.empty(snakemake.output.pdf, snakemake.output.png)
        sys.exit(0)
    # the first retrieved trial, else attached, else the fastest, whose five moments are in order
    order = pd.concat([trials[trials.retrieved], trials[trials.attached & ~trials.retrieved],
                       trials[~trials.attached].sort_values("v_peak_mps", ascending=False)])
    raw = I.groups.rsplit("/groups", 1)[0]
    for _, pick in order.iterrows():
        mc, _, meta = load.group(raw, pick.group_id)
        try:
            times = F.moments(mc, meta, P.ee_m, from_params(P.protocol).sampling.max_gap_s)
            break
        except ValueError as e:  # e.g. the cup never came closer to the block after the release
            print(f"not drawn: {e}", file=sys.stderr)
    else:
        F.empty(snakemake.output.pdf, snakemake.output.png,
                "no trial with its five moments in order (logs/fig_deployment.log)")
        sys.exit(0)
    top = F.recorded_frames(mc, meta, times, P.ee_m, from_params(P.protocol).sampling.max_gap_s)
    sim, _ = for_job(I, P)
    bottom = F.predicted_frames(sim, meta, times, top[0]["points"], P.ee_m)
    for b, t in zip(bottom, top):
        b["block"] = t["block"]
    bearing = float(meta["program"]["bearing"])
    base = np.asarray(top[0]["points"][0])
    what = "retrieved" if pick.retrieved else "attached" if pick.attached else "no attachment in this run"
    print(f"trial {pick.group_id} ({what}); moments {times}", file=sys.stderr)
    axis0 = np.asarray(meta["axis"], float)  # the hanging axis: where the arm leaves its base
    F.plot(F.render(top, base, bearing, axis0), F.render(bottom, base, bearing, axis0),
           [f"{k} ({times[k]:.2f} s)" for k in F.MOMENTS],
           f"{pick.group_id}, placement {int(pick.placement)}: {what}; peak tip speed {pick.v_peak_mps:.2f} m/s",
           snakemake.output.pdf, snakemake.output.png)
