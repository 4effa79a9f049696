"""Figure 0, the recordings at a glance: what was recorded, in which session, how long, how well tracked."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..rawformat import CATEGORIES, EVIDENCE_SETS
from . import style


def plot_overview(manifest: dict, pdf: str, png: str) -> None:
    style.setup()
    import matplotlib.pyplot as plt

    g = pd.DataFrame(manifest["groups"])
    sets = [s for s in EVIDENCE_SETS if s in set(g.evidence_set)]
    fig, ax = plt.subplots(1, 4, figsize=(style.TEXT_WIDTH_IN, 2.0), layout="constrained")

    # (a) groups per evidence set, stacked by category
    bottom = np.zeros(len(sets))
    for ci in range(max(len(c) for c in CATEGORIES.values())):
        n = [
            (g[(g.evidence_set == s) & (g.category == CATEGORIES[s][ci])].shape[0] if ci < len(CATEGORIES[s]) else 0)
            for s in sets
        ]
        ax[0].barh(sets, n, left=bottom, color=style.PALETTE[ci], height=0.7)
        bottom += n
    for y, n in enumerate(bottom):
        ax[0].text(n, y, f" {int(n)}", va="center", fontsize=6)
    ax[0].invert_yaxis()
    ax[0].set_xlabel("groups (bars split by category)")
    style.panel_label(ax[0], "a")

    # (b) groups per session and evidence set
    tab = g.pivot_table(index="evidence_set", columns="session", values="group_id", aggfunc="count", fill_value=0)
    tab = tab.reindex(sets)
    im = ax[1].imshow(tab.to_numpy(), aspect="auto", cmap="Blues")
    ax[1].set_yticks(range(len(sets)), [""] * len(sets))
    ax[1].set_xticks(range(tab.shape[1]), [c.lstrip("s") for c in tab.columns], fontsize=5)
    ax[1].set_xlabel("session")
    fig.colorbar(im, ax=ax[1], shrink=0.8, label="groups")
    style.panel_label(ax[1], "b")

    # (c) recording durations
    ax[2].boxplot([g[g.evidence_set == s].duration_s for s in sets], orientation="horizontal", widths=0.6,
                  flierprops={"markersize": 2})
    ax[2].set_yticks(range(1, len(sets) + 1), [""] * len(sets))
    ax[2].invert_yaxis()
    ax[2].set_xlabel("duration (s)")
    style.panel_label(ax[2], "c")

    # (d) motion-capture tracking
    ax[3].hist(100 * g.mocap_valid_fraction, bins=30, color=style.PALETTE[0])
    ax[3].set_xlabel("valid mocap samples (%)")
    ax[3].set_ylabel("groups")
    style.panel_label(ax[3], "d")
    style.save(fig, pdf, png)
