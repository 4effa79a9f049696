"""Tendon kinematics (paper III-A, Eq. 1) from the calibration bursts.

Eq. 1, for a taut tendon j terminating in section s(j):
    k w_j = sum_{p <= s(j)} [ d_p theta_p cos(phi_p - alpha_j) + dL_p ]
In ticks: w_j = sum_p (d_p/k) theta_p cos(phi_p - alpha_j) + c. A slack tendon has paid out more
than the path needs (w_j below the right side: an inequality), so the lever ratios d_p/k are
fitted to the upper (taut) envelope by quantile regression. A taut tendon is also stretched by its
tension (series compliance of cable and spool), which would read as extra lever; the holding
current measures that tension, so it enters as one more regressor.

Rows are quasi-static: medians over the hold plateau of each burst and over the rest before it.
"""

from __future__ import annotations

import numpy as np
from sklearn.linear_model import QuantileRegressor

from .. import rawformat as RF
from . import mocap as M

SETTLE_S = 0.5  # s after the step before the plateau counts as quasi-static
EDGE_S = 0.02  # s kept clear of each command step (log timing jitter): a fit margin, not a protocol value


def burst_rows(mc, sv, meta, max_gap_s: float) -> list[dict]:
    """One row per tendon and quasi-static window of a burst: Eq. 1 features, w, current."""
    th, ph = M.section_bends(mc, max_gap_s)
    t, ts = mc.t.to_numpy(), sv.t.to_numpy()
    lab = meta["labels"]
    rows = []
    for window, (lo, hi) in (("rest", (0.05, lab["t_up"] - EDGE_S)),
                             ("hold", (lab["t_up"] + SETTLE_S, lab["t_down"] - EDGE_S))):
        m, ms = (t > lo) & (t < hi), (ts > lo) & (ts < hi)
        if m.sum() < 3 or ms.sum() < 2:
            continue
        for s in (1, 2, 3):
            for k in (1, 2, 3):
                j = RF.servo_id(s, k)
                a = np.radians(RF.tendon_azimuth_deg(k))
                f = [float(np.nanmedian(th[m, p] * np.cos(ph[m, p] - a))) if p < s else 0.0 for p in range(3)]
                rows.append(dict(window=window, section=s, servo=j, commanded=s == meta["program"]["section"],
                                 f1=f[0], f2=f[1], f3=f[2],
                                 w=float(np.median(sv[f"present_{j}"].to_numpy()[ms])),
                                 current=float(np.median(sv[f"current_{j}"].to_numpy()[ms]))))
    return rows


def fit_levers(rows, quantile: float) -> dict:
    """d_p/k (ticks/rad) for S1..S3 by quantile regression of w on Eq. 1's features and the load."""
    # Current of an unloaded servo: the median over the rests before the bursts.
    rest = [r["current"] for r in rows if r.get("window") == "rest"]
    idle = float(np.median(rest)) if rest else float(np.min([r["current"] for r in rows]))
    X = np.array([[r["f1"], r["f2"], r["f3"], max(r["current"] - idle, 0.0)] for r in rows])
    y = np.array([r["w"] for r in rows])
    q = QuantileRegressor(quantile=quantile, alpha=0.0, solver="highs").fit(X, y)
    return dict(lever_ticks_per_rad=[float(c) for c in q.coef_[:3]], stretch_ticks_per_ma=float(q.coef_[3]),
                intercept_ticks=float(q.intercept_), idle_ma=idle, quantile=quantile, n_rows=len(y))


def travel_per_tick_um(rows, lever: dict, tendon_radius_m) -> dict:
    """Tendon travel per tick (um): Eq. 1 with the guides' radial offsets d_p in metres, over the
    commanded, loaded tendons of each hold: path shortening / (ticks less the load stretch)."""
    ks = []
    for r in rows:
        if r["window"] != "hold" or not r["commanded"] or r["current"] < lever["idle_ma"] + 10:
            continue
        path = sum(d * r[f"f{p + 1}"] for p, d in enumerate(tendon_radius_m))
        ticks = r["w"] - lever["intercept_ticks"] - lever["stretch_ticks_per_ma"] * (r["current"] - lever["idle_ma"])
        if path > 0 and ticks > 50:
            ks.append(path / ticks * 1e6)
    ks = np.array(ks)
    if not len(ks):
        return dict(median=float("nan"), iqr=[float("nan")] * 2, n=0)
    return dict(median=float(np.median(ks)), iqr=[float(x) for x in np.percentile(ks, [25, 75])], n=len(ks))
