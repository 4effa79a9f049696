"""What the simulated rig shows, computed only from its recordings (mocap, servo log, meta.json),
the way the pipeline reads them. Never reads simulator internals or twin_truth.json.

Tip speed and section bend rates are read exactly as the characterisation stage reads them
(`embodied_snap.characterize.mocap`): the `tip` body at 240 Hz, short dropouts bridged, a 3-sample
moving average, central differences; section rate = angular speed of the relative rotation
base->s1, s1->s2, s2->tip. Peaks are taken from the release start on. Tendon ceilings are the
paper's Eq. 2 with the protocol's rated servo speed (config rig.rated_speed_tick_s) and the paper's
calibrated d_p/k (hardware figures, not twin truth); the snap speed is read over the protocol's
timing set and attachments against its attachment threshold.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .. import rawformat as RF
from ..characterize.load import release_start
from ..characterize.mocap import on_grid, peak, section_rates, tip_speed
from ..io import read_parquet
from ..protocol import Protocol

PAPER_LEVER = (2351.0, 1411.0, 1390.0)  # d_p/k of the paper's arm: its Eq. 2 ceilings
# Peaks are taken from slightly before the release starts (the 3-sample smoothing reaches back).
LEAD_S = 0.05


def phenomena(raw_dir: str | Path, groups: "pd.DataFrame", proto: Protocol) -> dict:
    """The issue's table, from the recordings (proto: its sampling, rig, primitive and thresholds sections)."""
    ceiling = tuple(proto.rig.rated_speed_tick_s / x for x in PAPER_LEVER)  # rad/s, S1..S3
    timing, v_attach = proto.primitive.timing_s, proto.thresholds.attach_speed_mps
    g = pd.DataFrame(groups)
    rows = []
    for _, row in g.iterrows():
        if row.evidence_set not in ("release_mode", "delay_sweep", "attachment"):
            continue
        p = RF.group_paths(raw_dir, row.group_id)
        meta = RF.read_meta(p["meta"])
        mc = on_grid(read_parquet(p["mocap"]))
        t, t0 = mc.t.to_numpy(), release_start(meta) - LEAD_S
        v, _ = peak(tip_speed(mc, proto.sampling.max_gap_s), t, t0)
        rec = dict(
            group_id=row.group_id,
            es=row.evidence_set,
            cat=row.category,
            v=v,
            tau=meta["program"].get("tau"),
            attached=meta["labels"].get("attached"),
        )
        if row.evidence_set == "delay_sweep":
            rec["rates"] = [peak(w, t, t0)[0] for w in section_rates(mc, proto.sampling.max_gap_s).T]
        rows.append(rec)
    d = pd.DataFrame(rows)
    out: dict = {}

    def med(mask):
        x = d.v[mask].dropna()
        return float(np.median(x)) if len(x) else None

    if len(d) == 0:
        return dict(n_groups=0)
    rel = d.es == "release_mode"
    out["direct_release_tip_speed_mps"] = med(rel & (d.cat == "direct"))
    inst = d.v[rel & (d.cat == "instantaneous")].dropna()
    out["instant_release_fraction_over_1mps"] = float((inst > v_attach).mean()) if len(inst) else None
    out["n_instantaneous"] = int(len(inst))
    ramp = d.v[rel & (d.cat == "ramped")].dropna()
    out["ramped_tip_speed_mps_quantiles"] = (
        [float(x) for x in np.quantile(ramp, [0.1, 0.5, 0.9])] if len(ramp) else None
    )
    sw = d[d.es == "delay_sweep"]
    if len(sw):
        op = sw[(sw.tau >= timing[0] - 1e-9) & (sw.tau <= timing[1] + 1e-9)]
        out["snap_tip_speed_mps"] = float(np.median(op.v)) if len(op) else None
        if len(op):
            r = np.median(np.array(list(op.rates)), axis=0)
            out["snap_section_rate_dps"] = [float(np.degrees(x)) for x in r]
            out["snap_section_rate_ratio"] = [float(x / c) for x, c in zip(r, ceiling)]
        by = sw.groupby("tau").v.median()
        out["delay_sweep_peak_speed_by_tau"] = {f"{k:.3f}": float(v) for k, v in by.items()}
        out["delay_sweep_best_tau_s"] = float(by.idxmax())
        out["delay_sweep_best_tau_interior"] = bool(by.index.min() < by.idxmax() < by.index.max())
        lo, hi = sw[sw.tau <= 0.30 + 1e-9], sw[sw.tau >= 0.45 - 1e-9]
        out["delay_sweep_attach_le_030"] = float(lo.attached.astype(float).mean()) if len(lo) else None
        out["delay_sweep_attach_ge_045"] = float(hi.attached.astype(float).mean()) if len(hi) else None
        out["delay_sweep_n"] = [int(len(lo)), int(len(hi))]
    if out.get("snap_tip_speed_mps") and out.get("direct_release_tip_speed_mps"):
        out["snap_over_direct"] = out["snap_tip_speed_mps"] / out["direct_release_tip_speed_mps"]
    att = d[d.es == "attachment"]
    if len(att):
        a = att.attached.astype(bool)
        out["attach_below_1mps"] = int((a & (att.v < v_attach)).sum())
        out["attachment_n"] = int(len(att))
        out["attachment_rate"] = float(a.mean())
    return out
