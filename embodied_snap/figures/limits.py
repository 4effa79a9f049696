"""Figure 2: actuation limits. (a) Eq. 2 bend-rate ceilings beside the snap's section rates,
(b) peak tip speed per release mode with the direct range shaded and the 1 m/s line,
(c) attachment outcomes over tip speed and cup-axis tilt with the fitted model's contours."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from ..characterize.attachment import probability
from . import style

MODES = (("direct", "Direct"), ("ramped", "Ramped"), ("instantaneous", "Instant."))


def plot_limits(servo: dict, release: dict, attachment: dict, pdf: str, png: str, seed: int = 0, *,
                attach_speed_mps: float) -> None:
    """attach_speed_mps: the protocol's attachment threshold, drawn as the dashed line in (b, c)."""
    style.setup()
    fig, axes = plt.subplots(1, 3, figsize=(style.TEXT_WIDTH_IN, 2.2), gridspec_kw=dict(wspace=0.45))
    c_ceil, c_snap, c_ok, c_no = style.PALETTE[0], style.PALETTE[1], style.PALETTE[2], style.PALETTE[7]

    # (a) ceilings (Eq. 2, rated speed over calibrated lever) and the operating-point snap rates
    ax = axes[0]
    x = np.arange(3)
    ceil = np.degrees(servo["ceiling_rad_s"])
    snap = np.array(release["operating_section_rate_dps"])
    ax.bar(x - 0.19, ceil, 0.38, color=c_ceil, label="Tendon ceiling")
    ax.bar(x + 0.19, snap, 0.38, color=c_snap, label="Snap (op. point)")
    for i, (c, s) in enumerate(zip(ceil, snap)):
        if np.isfinite(s):
            ax.text(i + 0.19, s, f"{s / c:.1f}x", ha="center", va="bottom", fontsize=6.5)
    ax.set_xticks(x, ["S1", "S2", "S3"])
    ax.set_ylabel("Bend rate (deg/s)")
    ax.set_ylim(0, 1.4 * np.nanmax(np.r_[ceil, snap]))
    ax.legend(frameon=False, loc="upper left", fontsize=6.5, handlelength=1.2)
    style.panel_label(ax, "a")

    # (b) peak tip speed per release mode
    ax = axes[1]
    lo, hi = release["direct_range_mps"]
    ax.axhspan(lo, hi, color=c_ceil, alpha=0.18, lw=0, label="Direct range")
    ax.axhline(attach_speed_mps, color="k", ls="--", lw=0.8, label=f"{attach_speed_mps:g} m/s")
    rng = np.random.default_rng(seed)  # horizontal jitter of the dots only
    for i, (key, _) in enumerate(MODES):
        v = np.array(release["speeds"][key])
        if not len(v):
            continue
        ax.boxplot(v, positions=[i], widths=0.5, showfliers=False, medianprops=dict(color="k"),
                   whiskerprops=dict(lw=0.7), capprops=dict(lw=0.7), boxprops=dict(lw=0.7))
        ax.scatter(i + rng.uniform(-0.16, 0.16, len(v)), v, s=5, color=style.PALETTE[i + 3], alpha=0.8, lw=0, zorder=3)
    ax.set_xticks(range(3), [m[1] for m in MODES])
    ax.set_ylabel("Peak tip speed (m/s)")
    ax.set_ylim(0, 1.25 * max(max(release["speeds"][k] or [1.0]) for k, _ in MODES))
    ax.legend(frameon=False, loc="upper left", fontsize=6.5, ncol=2, handlelength=1.5, columnspacing=0.8)
    style.panel_label(ax, "b")

    # (c) attachment over speed and cup tilt, with the logistic model's contours
    ax = axes[2]
    tr = attachment["trials"]
    v = np.array([t["v"] for t in tr])
    tilt = np.array([t["tilt"] for t in tr])
    ok = np.array([t["attached"] for t in tr], bool)
    if "coef" in attachment and len(v):
        lo_v, hi_v, top = 0.9 * v.min(), 1.05 * v.max(), max(180, tilt.max())
        V, A = np.meshgrid(np.linspace(lo_v, hi_v, 100), np.linspace(0, top, 100))
        levels = [0.25, 0.5, 0.75]
        cs = ax.contour(V, A, probability(attachment, V, A), levels=levels, colors="0.45", linewidths=0.7)
        # Labels where each (straight) contour crosses 15 % of the speed range, if that is in view.
        b0, (bv, bt) = attachment["intercept"], attachment["coef"]
        x = lo_v + 0.15 * (hi_v - lo_v)
        at = [(x, (np.log(p / (1 - p)) - b0 - bv * x) / bt) for p in levels] if bt else []
        at = [(a, b) for a, b in at if 5 < b < top - 5]
        if at:
            ax.clabel(cs, fontsize=6, fmt="%.2f", manual=at)
        ax.set_xlim(lo_v, hi_v)
    ax.scatter(v[ok], tilt[ok], s=9, color=c_ok, lw=0, label="Attached")
    ax.scatter(v[~ok], tilt[~ok], s=9, facecolors="none", edgecolors=c_no, lw=0.6, label="Missed")
    ax.axvline(attach_speed_mps, color="k", ls="--", lw=0.8)
    ax.set_xlabel("Peak tip speed (m/s)")
    ax.set_ylabel("Cup-axis tilt (deg)")
    ax.legend(frameon=False, fontsize=6.5, loc="upper left", bbox_to_anchor=(0, 1.13), ncol=2,
              handletextpad=0.2, columnspacing=0.8)
    style.panel_label(ax, "c")

    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.2, top=0.88)
    style.save(fig, pdf, png)
