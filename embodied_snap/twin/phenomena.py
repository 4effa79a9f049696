"""What the simulated rig shows, computed only from its recordings (mocap, servo log, meta.json),
the way the pipeline reads them. Never reads simulator internals or twin_truth.json.

Tip speed: the `tip` body (distal end of S3) at 240 Hz, valid samples only, a 3-sample moving
average, central differences; the peak after the release starts. Section rate: the angular speed
of the relative rotation base->s1, s1->s2, s2->tip, same differencing. Tendon ceilings are the
paper's Eq. 2 with its rated 3140 tick/s and its calibrated d_p/k (hardware figures, not twin truth).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .. import rawformat as RF

RATED = 3140.0
PAPER_LEVER = (2351.0, 1411.0, 1390.0)
CEILING = tuple(RATED / x for x in PAPER_LEVER)  # rad/s, S1..S3
OPERATING_TAU = (0.45, 0.675)


MAX_GAP_S = 0.1  # dropouts up to this long are bridged (config resample.max_gap_s)


def _bridged(mc: pd.DataFrame, cols: list[str], body: str) -> np.ndarray:
    """Columns of one body on the 240 Hz grid, dropouts bridged linearly up to MAX_GAP_S
    (longer gaps stay NaN), like the resampling stage does."""
    x = mc[cols].copy()
    x[~mc[f"{body}_valid"].to_numpy(bool)] = np.nan
    lim = int(round(MAX_GAP_S * RF.MOCAP_HZ))
    return x.interpolate(limit=lim, limit_area="inside").to_numpy()


def _speed(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Central-difference speed of a 3-sample moving average (NaN where undefined)."""
    xs = (x[:-2] + x[1:-1] + x[2:]) / 3  # centred at samples 1..n-2
    v = np.full(len(t), np.nan)
    v[2:-2] = np.linalg.norm(xs[2:] - xs[:-2], axis=1) / (t[3:-1] - t[1:-3])
    return v


def tip_speed(mc: pd.DataFrame, t_from: float = 0.0) -> tuple[float, float]:
    """(peak tip speed m/s, its time) after t_from."""
    t = mc.t.to_numpy()
    x = _bridged(mc, ["tip_x", "tip_y", "tip_z"], "tip")
    v = _speed(x, t)
    v[t < t_from - 0.05] = np.nan
    if np.all(np.isnan(v)):
        return float("nan"), float("nan")
    k = int(np.nanargmax(v))
    return float(v[k]), float(t[k])


def _qconj(q):
    return q * np.array([1, -1, -1, -1])


def section_rates(mc: pd.DataFrame, t_from: float = 0.0) -> list[float]:
    """Peak relative angular speed (rad/s) of S1, S2, S3 from the body orientations."""
    from .mocap import qmul

    bodies = ("base", "s1", "s2", "tip")
    t = mc.t.to_numpy()
    Q = []
    for b in bodies:
        q = _bridged(mc, [f"{b}_qw", f"{b}_qx", f"{b}_qy", f"{b}_qz"], b)
        Q.append(q / np.linalg.norm(q, axis=1, keepdims=True))
    out = []
    for s in range(3):
        rel = qmul(_qconj(Q[s]), Q[s + 1])
        d = qmul(_qconj(rel[:-2]), rel[2:])  # rotation over two samples, centred
        ang = 2 * np.arctan2(np.linalg.norm(d[:, 1:], axis=1), np.abs(d[:, 0]))
        w = np.full(len(t), np.nan)
        w[1:-1] = ang / (t[2:] - t[:-2])
        w[1:-1] = (w[:-2] + w[1:-1] + w[2:]) / 3  # same 3-sample smoothing as the speed
        w[t < t_from - 0.05] = np.nan
        out.append(float(np.nanmax(w)) if np.any(~np.isnan(w)) else float("nan"))
    return out


def _release_start(meta: dict) -> float:
    lab = meta.get("labels", {})
    for k in ("t_slack", "t_release", "t_s2"):
        if k in lab:
            return float(lab[k])
    return 0.0


def phenomena(raw_dir: str | Path, groups: "pd.DataFrame") -> dict:
    """The issue's table, from the recordings."""
    g = pd.DataFrame(groups)
    rows = []
    for _, row in g.iterrows():
        if row.evidence_set not in ("release_mode", "delay_sweep", "attachment"):
            continue
        p = RF.group_paths(raw_dir, row.group_id)
        meta = RF.read_meta(p["meta"])
        mc = pd.read_parquet(p["mocap"])
        t0 = _release_start(meta)
        v, tv = tip_speed(mc, t0)
        rec = dict(group_id=row.group_id, es=row.evidence_set, cat=row.category, v=v, tau=meta["program"].get("tau"), attached=meta["labels"].get("attached"))
        if row.evidence_set == "delay_sweep":
            rec["rates"] = section_rates(mc, t0)
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
    out["instant_release_fraction_over_1mps"] = float((inst > 1.0).mean()) if len(inst) else None
    out["n_instantaneous"] = int(len(inst))
    ramp = d.v[rel & (d.cat == "ramped")].dropna()
    out["ramped_tip_speed_mps_quantiles"] = [float(x) for x in np.quantile(ramp, [0.1, 0.5, 0.9])] if len(ramp) else None
    sw = d[d.es == "delay_sweep"]
    if len(sw):
        op = sw[(sw.tau >= OPERATING_TAU[0] - 1e-9) & (sw.tau <= OPERATING_TAU[1] + 1e-9)]
        out["snap_tip_speed_mps"] = float(np.median(op.v)) if len(op) else None
        if len(op):
            r = np.median(np.array(list(op.rates)), axis=0)
            out["snap_section_rate_dps"] = [float(np.degrees(x)) for x in r]
            out["snap_section_rate_ratio"] = [float(x / c) for x, c in zip(r, CEILING)]
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
        out["attach_below_1mps"] = int((a & (att.v < 1.0)).sum())
        out["attachment_n"] = int(len(att))
        out["attachment_rate"] = float(a.mean())
    return out
