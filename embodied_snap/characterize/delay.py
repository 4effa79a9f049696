"""Delay sweep (paper III-B, Fig. 3b,c): peak tip speed and closest approach over the S1 delay tau,
attachment counts for tau <= 0.30 s and >= 0.45 s, and the timing interval the data support.
Held out: this sweep feeds no model fit, only this summary and the gates."""

from __future__ import annotations

import numpy as np
from statsmodels.stats.proportion import proportion_confint

from ..sources import recordings

SPEED_TOL = 0.97  # a delay is speed-optimal if its median peak speed is within 3% of the best


def summarize(rows) -> dict:
    r = [x for x in rows if x["tau"] is not None]
    tau = np.round(np.array([x["tau"] for x in r], float), 4)
    v = np.array([x["v_peak"] for x in r], float)
    att = np.array([bool(x["attached"]) for x in r])
    per = []
    for t in np.unique(tau):
        m = tau == t
        per.append(dict(tau=float(t), n=int(m.sum()), v_median=float(np.nanmedian(v[m])),
                        closest_median_m=float(np.nanmedian([r[i]["closest_m"] for i in np.flatnonzero(m)])),
                        attached=int(att[m].sum())))
    vm = np.array([p["v_median"] for p in per])
    best = int(np.nanargmax(vm))
    speed_taus = [p["tau"] for p, x in zip(per, vm) if x >= SPEED_TOL * vm[best]]
    # Supported interval: the contiguous run of tested delays around the speed optimum in which
    # every trial attached.
    ok = [p["attached"] == p["n"] for p in per]
    lo = hi = best
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    while hi < len(per) - 1 and ok[hi + 1]:
        hi += 1
    supported = [per[lo]["tau"], per[hi]["tau"]] if ok[best] else [float("nan")] * 2

    def count(m):
        k, n = int(att[m].sum()), int(m.sum())
        ci = [float(x) for x in proportion_confint(k, n, method="wilson")] if n else [float("nan")] * 2
        return dict(attached=k, n=n, fraction=k / n if n else float("nan"), ci95=ci)

    closest = np.array([x["closest_m"] for x in r], float)
    return dict(
        recordings=recordings([x["group_id"] for x in rows], [x["group_id"] for x in r], "no S1 delay in its program"),
        n=len(r),
        per_tau=per,
        closest_attached_median_m=float(np.nanmedian(closest[att])) if att.any() else float("nan"),
        best_tau_s=per[best]["tau"],
        speed_optimal_taus=[min(speed_taus), max(speed_taus)],
        supported_tau_s=supported,
        attach_le_030=count(tau <= 0.30 + 1e-9),
        attach_ge_045=count(tau >= 0.45 - 1e-9),
        trials=[
            dict(tau=float(a), v=float(b), closest=float(x["closest_m"]), attached=int(c))
            for a, b, c, x in zip(tau, v, att, r)
        ],
    )
