"""Fig. S1: is the architecture ranking robust? Drawn from results/robustness/summary.json alone.
(a) final held-out reward and (b) simulated attachment at the reporting tolerance, per architecture
(colour) and variant (group): one dot per optimisation seed, bar = mean; above each variant the
two-sided Mann-Whitney p of shared against the matched centralised controller (reward)."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from . import style
from .benchmark import COLORS, NAMES

TITLES = {"benchmark": "Benchmark", "uniform": "Uniform targets"}


def _title(v: str, x: dict) -> str:
    return TITLES.get(v, f"{v.capitalize()} budget\n({x['generations']} gen.)")


def seed_dots(ax, x0: float, y, w: float, color, rng, label=None) -> None:
    """One group's per-seed values as jittered dots (rng: the figure's fixed jitter) and their mean
    as a bar."""
    ax.plot(x0 + rng.uniform(-w / 4, w / 4, len(y)), y, "o", ms=2.8, color=color, alpha=0.8, label=label)
    if np.isfinite(y).any():
        ax.plot([x0 - w * 0.4, x0 + w * 0.4], [np.nanmean(y)] * 2, color=color, lw=1.4)


def p_text(p) -> str:
    return f"p = {p:.3g}" if p is not None else "p n/a"


def finish(fig, axes, ticks: list[str], ncol: int, room: float, pdf: str, png: str) -> None:
    """Two panels over groups: the groups' names under the lower one, room above the upper one for
    the p-values (a share of its range), one legend, panel labels a and b; saved."""
    axes[1].set_xticks(range(len(ticks)), ticks)
    axes[1].set_xlim(-0.5, len(ticks) - 0.5)
    lo, hi = axes[0].get_ylim()
    axes[0].set_ylim(lo, hi + room * (hi - lo))
    h, lab = axes[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="upper center", ncol=ncol, handlelength=1, frameon=False, fontsize=7)
    style.panel_label(axes[0], "a")
    style.panel_label(axes[1], "b")
    style.save(fig, pdf, png)


def plot_robustness(s: dict, pdf: str, png: str) -> None:
    style.setup()
    fig, axes = plt.subplots(2, 1, figsize=(style.TEXT_WIDTH_IN, 3.6), sharex=True)
    fig.subplots_adjust(left=0.11, right=0.99, bottom=0.14, top=0.88, hspace=0.12)
    variants = list(s)
    archs = s[variants[0]]["archs"]
    w = 0.8 / len(archs)
    rng = np.random.default_rng(0)  # fixed jitter: the same summary draws the same figure
    for ax, key, label in ((axes[0], "reward", "Final held-out reward"),
                           (axes[1], "attachment_report", "Attachment at 5 cm")):
        for i, v in enumerate(variants):
            for j, a in enumerate(archs):
                per = s[v][key].get(a, {}).get("per_seed", {})
                y = np.array([np.nan if e is None else e for e in per.values()], float)
                seed_dots(ax, i - 0.4 + w * (j + 0.5), y, w, COLORS.get(a), rng, NAMES.get(a, a) if i == 0 else None)
        ax.set_ylabel(label)
        for i in range(1, len(variants)):
            ax.axvline(i - 0.5, color="0.85", lw=0.6)
    for i, v in enumerate(variants):
        p = s[v]["reward_tests"].get("centralised", {}).get("p")
        holds = "ranking holds" if s[v]["ranking_reward_holds"] else "ranking differs"
        txt = p_text(p) + (f"; {holds}" if i else "")
        axes[0].text(i, 0.98, txt, transform=axes[0].get_xaxis_transform(), ha="center", va="top", fontsize=6.5)
    axes[1].set_ylim(0, 1)
    finish(fig, axes, [_title(v, s[v]) for v in variants], len(archs), 0.15, pdf, png)
