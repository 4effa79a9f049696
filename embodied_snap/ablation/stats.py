"""Intervals and tests of the release-rule ablation (paper V protocol: "Release-rule rates use
Wilson intervals over 400 targets and paired McNemar tests. Timing-reward intervals bootstrap
target families to account for repeated starts.")."""

from __future__ import annotations

import numpy as np
from scipy.stats import bootstrap
from statsmodels.stats.contingency_tables import mcnemar
from statsmodels.stats.proportion import proportion_confint


def wilson(successes: int, n: int, alpha: float = 0.05) -> list[float]:
    lo, hi = proportion_confint(int(successes), int(n), alpha=alpha, method="wilson")
    return [float(lo), float(hi)]


def paired_table(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """2x2 table of two paired boolean outcomes: rows a yes/no, columns b yes/no."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    return np.array([[(a & b).sum(), (a & ~b).sum()], [(~a & b).sum(), (~a & ~b).sum()]])


def mcnemar_p(a, b, exact_below: int = 25) -> dict:
    """Paired McNemar test of a against b; exact (binomial) when the discordant pairs are fewer
    than exact_below, else the chi-square form with continuity correction."""
    t = paired_table(a, b)
    disc = int(t[0, 1] + t[1, 0])
    exact = disc < exact_below
    p = 1.0 if disc == 0 else float(mcnemar(t, exact=exact, correction=True).pvalue)
    return dict(p=p, exact=exact, discordant=[int(t[0, 1]), int(t[1, 0])])


def family_bootstrap(values: np.ndarray, families: np.ndarray, seed: int, n_resamples: int = 2000,
                     level: float = 0.95) -> list[float]:
    """Percentile interval of the mean of `values` when whole target families are resampled: each
    resample draws families with replacement and averages all their starts (a family's starts are
    not independent)."""
    fam, inv = np.unique(np.asarray(families), return_inverse=True)
    sums = np.bincount(inv, weights=np.asarray(values, float), minlength=len(fam))
    counts = np.bincount(inv, minlength=len(fam)).astype(float)
    if len(fam) < 2:
        m = float(sums.sum() / counts.sum())
        return [m, m]

    def mean_of(idx, axis=-1):
        idx = idx.astype(int)
        return sums[idx].sum(axis) / counts[idx].sum(axis)

    res = bootstrap((np.arange(len(fam)),), mean_of, n_resamples=n_resamples, confidence_level=level,
                    method="percentile", vectorized=True, rng=np.random.default_rng(seed))
    return [float(res.confidence_interval.low), float(res.confidence_interval.high)]
