"""Figure 6: release-rule ablation in simulation, drawn from results/ablation/summary.json alone.
(a) S1 timing reward (mean Eq. 10 reward) per rule and the two references, bars: target-family
bootstrap 95 % intervals; (b) attachment at the reporting tolerance per rule, Wilson 95 % bars,
annotated with the fraction of releases projected to a timing bound and the paired McNemar p
against target-only release; (c) attachment versus lateral tolerance, learned policy and the best
fixed primitive."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from . import style

NAMES = {"target_only": "Target-only", "clock": "Clock", "s1_rate": "S1 local", "tip_speed": "Tip speed",
         "s2_peak": "S2 neighbour", "family_clock": "Family clock", "oracle": "Start oracle"}
RULES = ("target_only", "clock", "s1_rate", "tip_speed", "s2_peak")
REFS = ("family_clock", "oracle")


def _p(p: float) -> str:
    return f"p={p:.2g}" if p >= 1e-3 else f"p={p:.0e}"


def plot_ablation(s: dict, pdf: str, png: str) -> None:
    style.setup()
    fig, axes = plt.subplots(1, 3, figsize=(style.TEXT_WIDTH_IN, 2.3))
    fig.subplots_adjust(left=0.1, right=0.99, bottom=0.25, top=0.9, wspace=0.42)
    R = s["rules"]

    # (a) timing reward per rule; the references in grey
    ax = axes[0]
    names = [*RULES, *REFS]
    for i, r in enumerate(names):
        m, (lo, hi) = R[r]["reward_mean"], R[r]["reward_ci"]
        c = style.PALETTE[0] if r in RULES else "0.5"
        ax.errorbar(i, m, yerr=[[m - lo], [hi - m]], fmt="o", ms=3.5, color=c, capsize=2, lw=1)
    ax.set_xticks(range(len(names)), [NAMES[r] for r in names], rotation=35, ha="right")
    ax.set_ylabel("S1 timing reward")
    style.panel_label(ax, "a")

    # (b) attachment at the reporting tolerance, Wilson bars, projected fraction and McNemar p
    ax = axes[1]
    for i, r in enumerate(RULES):
        a, (lo, hi) = R[r]["attachment"], R[r]["attachment_ci"]
        ax.bar(i, a, color=style.PALETTE[0] if r == "target_only" else style.PALETTE[5], width=0.7)
        ax.errorbar(i, a, yerr=[[a - lo], [hi - a]], fmt="none", color="k", capsize=2, lw=0.8)
        note = f"{R[r]['at_bound_fraction']:.0%}"
        if "mcnemar" in R[r]:
            note += "\n" + _p(R[r]["mcnemar"]["p"])
        ax.text(i, min(hi + 0.02, 1.0), note, ha="center", va="bottom", fontsize=6)  # label just above the bar
    ax.set_xticks(range(len(RULES)), [NAMES[r] for r in RULES], rotation=35, ha="right")
    ax.set_ylim(0, 1.2)
    ax.set_yticks(np.linspace(0, 1, 6))
    ax.set_ylabel(f"Attachment at {s['report_tolerance_m'] * 100:.0f} cm (n={R['target_only']['n']})")
    style.panel_label(ax, "b")

    # (c) attachment versus tolerance
    ax = axes[2]
    sw = s["sweep"]
    r_cm = np.array(sw["tolerances_m"]) * 100
    ax.plot(r_cm, sw["learned"], color=style.PALETTE[0], lw=1.1, label="Learned policy")
    ax.plot(r_cm, sw["fixed"], color=style.PALETTE[7], lw=1.1, ls="--", label="Best fixed primitive")
    ax.axvline(s["report_tolerance_m"] * 100, color="0.5", ls=":", lw=0.8)
    ax.set_xlabel("Lateral tolerance $r$ (cm)")
    ax.set_ylabel("Simulated attachment rate")
    ax.set_xlim(r_cm.min(), r_cm.max())
    ax.set_ylim(0, 1)
    ax.legend(loc="lower right", framealpha=1, edgecolor="none")
    style.panel_label(ax, "c")
    style.save(fig, pdf, png)
