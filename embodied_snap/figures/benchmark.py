"""Figure 5: architecture benchmark under a common simulation protocol, drawn from
results/policy/summary.json alone. (a) Held-out reward vs simulator evaluations (line: mean, band:
min-max over seeds); (b) simulated attachment (Eq. 11) on the evaluation targets vs lateral tolerance
(mean +- SD over seeds) with the best fixed primitive; (c) evaluations to reach the matched
centralised seeds' mean final reward, one dot per seed, crosses at the budget for seeds that never do."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from ..policy.architectures import TABLE
from . import style

# Labels and colours: the architectures' table (policy/architectures.py), and the fixed primitive's.
NAMES = {a.name: a.label for a in TABLE} | {"fixed": "Fixed primitive"}
COLORS = {a.name: style.PALETTE[a.colour] for a in TABLE} | {"fixed": style.PALETTE[7]}
SCALE = 1e4  # evaluations axis in units of 10^4


def _label(s: dict, arch: str) -> str:
    return f"{NAMES.get(arch, arch)} ({s['n_params'][arch]})" if arch in s["n_params"] else NAMES.get(arch, arch)


def plot_benchmark(s: dict, pdf: str, png: str) -> None:
    style.setup()
    fig, axes = plt.subplots(1, 3, figsize=(style.TEXT_WIDTH_IN, 2.3))
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.19, top=0.9, wspace=0.38)
    archs, budget = s["archs"], s["budget_evaluations"]
    reach = s.get("reach") or {}

    # (a) held-out reward on the 64 selection targets over the search
    ax = axes[0]
    for a in archs:
        c = s["curves"][a]
        x = np.array(c["evaluations"]) / SCALE
        ax.fill_between(x, c["min"], c["max"], color=COLORS.get(a), alpha=0.2, lw=0)
        ax.plot(x, c["mean"], color=COLORS.get(a), lw=1.1, label=f"{_label(s, a)}, n={c['n_seeds']}")
    if reach.get("level") is not None:
        ax.axhline(reach["level"], color="0.5", ls=":", lw=0.8)
    ax.set_xlabel(r"Simulator evaluations ($\times10^4$)")
    ax.set_ylabel("Held-out reward")
    ax.set_xlim(0, budget / SCALE)
    style.panel_label(ax, "a")

    # (b) attachment vs lateral tolerance; the fixed primitive is one policy, so it has no band
    ax = axes[1]
    sw = s["attachment_sweep"]
    r_cm = np.array(sw["tolerances_m"]) * 100
    for a in archs + ["fixed"]:
        row = sw["archs"].get(a)
        if row is None:
            continue
        m = np.array(row["mean"], float)
        sd = np.array([np.nan if v is None else v for v in row["sd"]], float)
        fixed = a == "fixed"
        if not fixed and np.isfinite(sd).any():
            ax.fill_between(r_cm, m - sd, m + sd, color=COLORS.get(a), alpha=0.2, lw=0)
        ax.plot(r_cm, m, color=COLORS.get(a), lw=1.1, ls="--" if fixed else "-",
                label=NAMES["fixed"] if fixed else None)
    ax.axvline(s["report_tolerance_m"] * 100, color="0.5", ls=":", lw=0.8)
    ax.set_xlabel("Lateral tolerance $r$ (cm)")
    ax.set_ylabel("Simulated attachment rate")
    ax.set_xlim(r_cm.min(), r_cm.max())
    ax.set_ylim(0, 1)
    # One legend for all panels (colours mean the same architecture everywhere), here below the
    # curves, where (a)'s bands would run under it.
    h, lab = axes[0].get_legend_handles_labels()
    hf, lf = ax.get_legend_handles_labels()
    ax.legend(h + hf, lab + lf, loc="lower right", handlelength=1.4, framealpha=1, edgecolor="none",
              borderaxespad=0.2)
    style.panel_label(ax, "b")

    # (c) evaluations to reach the matched centralised mean final reward
    ax = axes[2]
    rng = np.random.default_rng(0)  # fixed jitter: the same summary draws the same figure
    for i, a in enumerate(archs):
        per = (reach.get("per_arch") or {}).get(a, {}).get("per_seed", {})
        v = np.array([np.nan if e is None else e for e in per.values()], float)
        x = i + rng.uniform(-0.15, 0.15, len(v))
        hit = np.isfinite(v)
        ax.plot(x[hit], v[hit] / SCALE, "o", ms=3.5, color=COLORS.get(a), alpha=0.85)
        ax.plot(x[~hit], np.full((~hit).sum(), budget / SCALE), "x", ms=4.5, mew=1.2, color=COLORS.get(a))
        if hit.any():
            ax.plot([i - 0.25, i + 0.25], [np.median(v[hit]) / SCALE] * 2, color=COLORS.get(a), lw=1.2)
    ax.axhline(budget / SCALE, color="0.5", ls="--", lw=0.8)
    ax.text(len(archs) - 0.5, budget / SCALE, "budget", ha="right", va="bottom", color="0.4", fontsize=7)
    ax.set_xticks(range(len(archs)), [NAMES.get(a, a).replace("Centralised", "Central.") for a in archs],
                  rotation=20, ha="right")
    ax.set_xlim(-0.5, len(archs) - 0.5)
    ax.set_ylim(0, budget / SCALE * 1.1)
    ax.set_ylabel(r"Evaluations to reach ($\times10^4$)")
    style.panel_label(ax, "c")
    style.save(fig, pdf, png)
