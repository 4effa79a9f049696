"""Fig. S2: does the architecture ranking depend on where the search starts? Drawn from
results/sensitivity/summary.json alone. (a) final held-out reward per architecture (colour) and start
(group): one dot per seed, bar = mean, above it the Mann-Whitney p of shared against centralised and
the reading; (b) the slope probe: mean cosine between the sections' preload slopes, open markers for
the start's first candidates, dots for the selected policies."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from . import style
from .benchmark import COLORS, NAMES
from .robustness import finish, p_text, seed_dots


def _title(i: int, x: dict) -> str:
    st = x["start"]
    return (f"{'zero' if st['init'] == 'zero' else 'Glorot'} weights\n$\\sigma_0$ = {st['sigma0']:g}"
            + ("\n(benchmark)" if i == 0 else ""))


def plot_sensitivity(s: dict, pdf: str, png: str) -> None:
    style.setup()
    fig, axes = plt.subplots(2, 1, figsize=(style.TEXT_WIDTH_IN, 3.8), sharex=True)
    fig.subplots_adjust(left=0.11, right=0.99, bottom=0.17, top=0.9, hspace=0.12)
    starts = list(s)
    archs = list(dict.fromkeys(a for x in s.values() for a in x["archs"]))
    w = 0.8 / len(archs)
    rng = np.random.default_rng(0)  # fixed jitter: the same summary draws the same figure
    labelled = set()
    for i, name in enumerate(starts):
        x = s[name]
        for j, a in enumerate(archs):
            x0 = i - 0.4 + w * (j + 0.5)
            c = COLORS.get(a)
            per = x["reward"].get(a, {}).get("per_seed", {})
            y = np.array([np.nan if e is None else e for e in per.values()], float)
            if len(y):
                seed_dots(axes[0], x0, y, w, c, rng, None if a in labelled else NAMES.get(a, a))
                labelled.add(a)
            cos = [p["cosine_mean"] for p in x["probe"].get(a, {}).values() if p["cosine_mean"] is not None]
            axes[1].plot(x0 + rng.uniform(-w / 4, w / 4, len(cos)), cos, "o", ms=2.8, color=c, alpha=0.8)
            if x["start_probe"].get(a) is not None:
                axes[1].plot(x0, x["start_probe"][a], "o", ms=5, mfc="none", mec=c, mew=0.9)
        p = x["reward_tests"].get("centralised", {}).get("p")
        verdict = {True: "reproduced", False: "not reproduced", None: "n/a"}[x["reproduced"]]
        axes[0].text(i, 0.98, p_text(p) + f"\n{verdict}",
                     transform=axes[0].get_xaxis_transform(), ha="center", va="top", fontsize=6.5)
    for ax in axes:
        for i in range(1, len(starts)):
            ax.axvline(i - 0.5, color="0.85", lw=0.6)
    axes[0].set_ylabel("Final held-out reward")
    axes[1].set_ylabel("Slope cosine\n(sections' preloads)")
    axes[1].set_ylim(-1.05, 1.05)
    axes[1].axhline(0, color="0.85", lw=0.6)
    finish(fig, axes, [_title(i, s[n]) for i, n in enumerate(starts)], len(archs), 0.25, pdf, png)
