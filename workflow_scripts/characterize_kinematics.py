"""Tendon kinematics (Eq. 1): lever ratios d_p/k and tendon travel per tick, from the bursts."""

import sys

from embodied_snap.characterize import kinematics as K
from embodied_snap.characterize import load
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.protocol import from_params
from embodied_snap.sources import recordings

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    p = snakemake.params
    gap = from_params(p.protocol).sampling.max_gap_s  # mocap dropouts bridged
    rows = [r for g in p.groups for r in K.burst_rows(*load.group(p.raw, g), gap)]
    fit = K.fit_levers(rows, p.quantile)
    fit["travel_per_tick_um"] = K.travel_per_tick_um(rows, fit, p.tendon_radius_m)
    fit["n_bursts"] = len(p.groups)
    fit["recordings"] = recordings(p.groups, p.groups)  # every burst enters the fit
    print(fit, file=sys.stderr)
    write_json(dict(fit, rows=rows), snakemake.output[0])
