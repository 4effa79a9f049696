"""Figure 0, the recordings at a glance: what was recorded, in which session, how long, how well tracked."""

from __future__ import annotations

import pandas as pd

from ..rawformat import CATEGORIES, EVIDENCE_SETS
from . import style


def plot_overview(manifest: dict, pdf: str, png: str) -> None:
    style.setup()
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    g = pd.DataFrame(manifest["groups"])
    sets = [s for s in EVIDENCE_SETS if s in set(g.evidence_set)]
    colour = {s: style.PALETTE[i % len(style.PALETTE)] for i, s in enumerate(sets)}
    fig, ax = plt.subplots(2, 2, figsize=(style.TEXT_WIDTH_IN, 4.4), layout="constrained")

    # (a) groups per evidence set and category (paper Table I)
    rows = [(s, c) for s in sets for c in CATEGORIES[s] if ((g.evidence_set == s) & (g.category == c)).any()]
    n = [int(((g.evidence_set == s) & (g.category == c)).sum()) for s, c in rows]
    a = ax[0, 0]
    a.barh(range(len(rows)), n, color=[colour[s] for s, _ in rows], height=0.7)
    for y, k in enumerate(n):
        a.text(k, y, f" {k}", va="center", fontsize=6)
    a.set_yticks(range(len(rows)), [f"{s} / {c}" if len(CATEGORIES[s]) > 1 else s for s, c in rows], fontsize=6)
    a.invert_yaxis()
    a.set_xlabel("acquisition groups")
    a.set_xlim(0, max(n) * 1.15)
    style.panel_label(a, "a")

    # (b) groups per session and evidence set: every set spans the session-to-session variation
    tab = g.pivot_table(index="evidence_set", columns="session", values="group_id", aggfunc="count", fill_value=0)
    tab = tab.reindex(sets)
    b = ax[0, 1]
    im = b.imshow(tab.to_numpy(), aspect="auto", cmap="Blues", vmin=0)
    b.set_yticks(range(len(sets)), sets, fontsize=6)
    b.set_xticks(range(tab.shape[1]), [c.lstrip("s") for c in tab.columns], fontsize=6)
    b.set_xlabel("session")
    cb = fig.colorbar(im, ax=b, shrink=0.9, label="groups")
    cb.locator = MaxNLocator(integer=True)
    cb.update_ticks()
    style.panel_label(b, "b")

    # (c) recording durations per evidence set
    c = ax[1, 0]
    bp = c.boxplot([g[g.evidence_set == s].duration_s for s in sets], orientation="horizontal", widths=0.6,
                   flierprops={"markersize": 2}, patch_artist=True, medianprops={"color": "k"})
    for patch, s in zip(bp["boxes"], sets):
        patch.set_facecolor(colour[s])
        patch.set_alpha(0.6)
    c.set_yticks(range(1, len(sets) + 1), sets, fontsize=6)
    c.invert_yaxis()
    c.set_xlabel("recording duration (s)")
    style.panel_label(c, "c")

    # (d) motion-capture tracking: dropouts are bridged when short, rejected when long
    d = ax[1, 1]
    for s in sets:
        d.hist(100 * g[g.evidence_set == s].mocap_valid_fraction, bins=20, histtype="step", color=colour[s], label=s)
    d.set_xlabel("valid motion-capture samples (%)")
    d.set_ylabel("groups")
    d.yaxis.set_major_locator(MaxNLocator(integer=True))
    d.legend(frameon=False, fontsize=5)
    style.panel_label(d, "d")
    style.save(fig, pdf, png)
