"""Figure 3: snap preconditions and timing. (a) P_snap(rho1, rho2) with the operating point,
(b) peak tip speed over the S1 delay, (c) closest approach of the cup face (embodied_snap.cup) and
attachment over the delay; shaded: the intervals the sweep supports."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from . import style


def plot_snap(snap: dict, sweep: dict, pdf: str, png: str, *, attach_speed_mps: float) -> None:
    """attach_speed_mps: the protocol's attachment threshold, drawn as the dashed line in (b)."""
    style.setup()
    fig, axes = plt.subplots(1, 3, figsize=(style.TEXT_WIDTH_IN, 2.2), gridspec_kw=dict(wspace=0.55))
    c_ok, c_no, c_band = style.PALETTE[2], style.PALETTE[7], style.PALETTE[0]

    # (a) P_snap map, the P = 0.8 contour, the training trials and the operating point
    ax = axes[0]
    g = snap["grid"]
    P = np.array(g["p"]).T  # rows rho2, columns rho1
    im = ax.pcolormesh(g["rho1"], g["rho2"], P, vmin=0, vmax=1, cmap="viridis", shading="auto", rasterized=True)
    if P.min() < 0.8 < P.max():
        ax.contour(g["rho1"], g["rho2"], P, levels=[0.8], colors="w", linewidths=0.8)
    tr = snap["trials"]
    ev = np.array([t["event"] for t in tr], bool)
    r1, r2 = np.array([t["rho1"] for t in tr]), np.array([t["rho2"] for t in tr])
    ax.scatter(r1[ev], r2[ev], s=5, color="w", lw=0, alpha=0.8)
    ax.scatter(r1[~ev], r2[~ev], s=6, marker="x", color="k", lw=0.6)
    ax.plot(*snap["operating_point"], marker="*", ms=9, color=style.PALETTE[4], mec="k", mew=0.5)
    ax.set_xlabel(r"$\rho_1$ (ticks)")
    ax.set_ylabel(r"$\rho_2$ (ticks)")
    cb = fig.colorbar(im, ax=ax, fraction=0.05, pad=0.03)
    cb.set_label(r"$P_\mathrm{snap}$", labelpad=2)
    cb.ax.tick_params(labelsize=6)
    style.panel_label(ax, "a")

    per = sweep["per_tau"]
    tau = np.array([t["tau"] for t in sweep["trials"]])
    att = np.array([t["attached"] for t in sweep["trials"]], bool)

    # (b) peak tip speed over tau, the speed-optimal delays shaded
    ax = axes[1]
    ax.axvspan(*_span(sweep["speed_optimal_taus"], per), color=c_band, alpha=0.18, lw=0)
    ax.scatter(tau, [t["v"] for t in sweep["trials"]], s=7, color=style.PALETTE[3], lw=0, alpha=0.8)
    ax.plot([p["tau"] for p in per], [p["v_median"] for p in per], color="k", lw=0.9)
    ax.axhline(attach_speed_mps, color="k", ls="--", lw=0.8)
    ax.set_xlabel(r"S1 delay $\tau$ (s)")
    ax.set_ylabel("Peak tip speed (m/s)")
    style.panel_label(ax, "b")

    # (c) closest approach over tau, filled = attached; the supported timing interval shaded
    ax = axes[2]
    if np.isfinite(sweep["supported_tau_s"]).all():
        ax.axvspan(*_span(sweep["supported_tau_s"], per), color=c_band, alpha=0.18, lw=0, label="Supported")
    d = np.array([t["closest"] for t in sweep["trials"]]) * 1e3
    ax.scatter(tau[att], d[att], s=9, color=c_ok, lw=0, label="Attached")
    ax.scatter(tau[~att], d[~att], s=9, facecolors="none", edgecolors=c_no, lw=0.6, label="Missed")
    ax.plot([p["tau"] for p in per], [p["closest_median_m"] * 1e3 for p in per], color="k", lw=0.9)
    ax.set_xlabel(r"S1 delay $\tau$ (s)")
    ax.set_ylabel("Cup closest approach (mm)")
    ax.legend(frameon=False, fontsize=6, loc="lower right", bbox_to_anchor=(1.02, 0.99), ncol=3,
              handletextpad=0.15, columnspacing=0.5, handlelength=0.9, borderaxespad=0)
    style.panel_label(ax, "c")

    fig.subplots_adjust(left=0.08, right=0.99, bottom=0.2, top=0.88)
    style.save(fig, pdf, png)


def _span(interval, per):
    """Shade an interval of tested delays out to half the spacing of the tested grid."""
    taus = sorted(p["tau"] for p in per)
    h = 0.5 * min(np.diff(taus)) if len(taus) > 1 else 0.025
    return interval[0] - h, interval[1] + h
