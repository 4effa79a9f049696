"""Release modes (paper III-A/B, Fig. 2b): peak tip speed of direct, ramped and instantaneous
releases; the direct-release range; ramped releases split at 1 m/s into fast snaps and slow
servo-dragged ones; the fraction of instantaneous releases above 1 m/s; section
bend rates at the operating point (the instantaneous releases are primitives around it) and their
ratio to the Eq. 2 ceilings. The 1 m/s is the protocol's attachment threshold, passed in."""

from __future__ import annotations

import numpy as np
from statsmodels.stats.proportion import proportion_confint

from ..sources import recordings


def summarize(rows, ceilings_rad_s, attach_speed_mps: float) -> dict:
    by = {c: np.array([r["v_peak"] for r in rows if r["category"] == c and np.isfinite(r["v_peak"])])
          for c in ("direct", "ramped", "instantaneous")}
    inst = by["instantaneous"]
    n_fast = int((inst > attach_speed_mps).sum())
    rates = np.array([r["rate_peak"] for r in rows if r["category"] == "instantaneous"], float)
    med_rates = np.nanmedian(rates, axis=0) if len(rates) else np.full(3, np.nan)
    q = lambda x, p: [float(v) for v in np.percentile(x, p)] if len(x) else [float("nan")] * len(p)  # noqa: E731
    used = [r["group_id"] for r in rows if r["category"] == "instantaneous"
            or (r["category"] in by and np.isfinite(r["v_peak"]))]
    return dict(
        recordings=recordings([r["group_id"] for r in rows], used, "no finite peak tip speed"),
        speeds={c: [float(v) for v in x] for c, x in by.items()},
        direct_range_mps=[float(by["direct"].min()), float(by["direct"].max())] if len(by["direct"]) else [np.nan] * 2,
        direct_median_mps=float(np.median(by["direct"])) if len(by["direct"]) else float("nan"),
        instant_n=int(len(inst)),
        instant_over_1mps=n_fast,
        instant_fraction_over_1mps=n_fast / len(inst) if len(inst) else float("nan"),
        instant_fraction_ci95=[float(x) for x in proportion_confint(n_fast, len(inst), method="wilson")]
        if len(inst)
        else [np.nan] * 2,
        operating_tip_speed_iqr_mps=q(inst, [25, 75]),
        operating_tip_speed_median_mps=float(np.median(inst)) if len(inst) else float("nan"),
        operating_section_rate_dps=[float(np.degrees(r)) for r in med_rates],
        operating_rate_over_ceiling=[float(r / c) for r, c in zip(med_rates, ceilings_rad_s)],
        snap_over_direct=float(np.median(inst) / np.median(by["direct"]))
        if len(inst) and len(by["direct"])
        else float("nan"),
        ramped_quantiles_mps=q(by["ramped"], [10, 50, 90]),
        # Fig. 2b: a ramped release either snaps (the fold latched) or is dragged open by the servos
        ramped_fast_n=int((by["ramped"] > attach_speed_mps).sum()),
        ramped_slow_n=int((by["ramped"] <= attach_speed_mps).sum()),
    )
