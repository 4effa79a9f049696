"""Servo rate: first-order fit over all calibration bursts; Eq. 2 ceilings from the fitted levers."""

import json
import sys

import numpy as np

from embodied_snap.characterize import load
from embodied_snap.characterize import servo as S
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.rawformat import goal_timing, servo_id
from embodied_snap.sources import recordings

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    p = snakemake.params
    bursts = []
    for g in p.groups:
        _, sv, meta = load.group(p.raw, g)
        ids = [servo_id(meta["program"]["section"], k) for k in (1, 2, 3)]
        bursts.append(dict(t=sv.t.to_numpy(), goal=sv[[f"goal_{i}" for i in ids]].to_numpy(float),
                           present=sv[[f"present_{i}" for i in ids]].to_numpy(float),
                           t_changes=(meta["labels"]["t_up"], meta["labels"]["t_down"]),
                           timing=goal_timing(meta)))
    fit = S.fit(bursts)
    # The rated no-load speed is a datasheet value (config rig.rated_speed_tick_s): Eq. 2 uses it
    # as the conservative ceiling.
    rated = from_params(snakemake.params.protocol).rig.rated_speed_tick_s
    lever = json.load(open(snakemake.input.kinematics))["lever_ticks_per_rad"]
    peaks = S.peak_rates(bursts)
    fit.update(n_bursts=len(bursts), rated_tick_s=rated, ceiling_rad_s=S.ceilings(rated, lever),
               peak_rate_over_rated_5_95=[float(x) for x in np.percentile(peaks / rated, [5, 95])],
               peak_rates_tick_s=peaks.tolist(), lever_ticks_per_rad=lever,
               recordings=recordings(p.groups, p.groups))  # every burst enters the fit
    print({k: v for k, v in fit.items() if k != "peak_rates_tick_s"}, file=sys.stderr)
    write_json(fit, snakemake.output[0])
