"""Figure 4: hardware gates for controller development. (a) Validation open-loop tip error over the
horizon for persistence and the GRU (band: seed range), (b) measured and predicted peak tip speed
over the excluded delay sweep, (c) measured and predicted tip travel; bands in (b, c) span seeds."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from . import style


def _band(ax, x, per_seed: np.ndarray, color, label):
    """Median line and min-max band over seeds (rows)."""
    ax.fill_between(x, per_seed.min(0), per_seed.max(0), color=color, alpha=0.25, lw=0)
    ax.plot(x, np.median(per_seed, 0), color=color, lw=1.1, label=label)


def plot_gates(persistence: dict, validation: list[dict], gate: dict, dt: float, horizon: int, pdf: str,
               png: str) -> None:
    """dt: the grid step of the horizons in `persistence` and `validation`; horizon: the trained
    rollout length in steps (both the protocol's)."""
    style.setup()
    fig, axes = plt.subplots(1, 3, figsize=(style.TEXT_WIDTH_IN, 2.2))
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.19, top=0.9, wspace=0.42)
    c_meas, c_gru, c_pers = style.PALETTE[7], style.PALETTE[0], style.PALETTE[1]

    # (a) tip error over the horizon; the trained horizon ends at 0.5 s, 0.7 s continues the rollout
    ax = axes[0]
    s = np.array(persistence["h"]) * dt
    ax.plot(s, persistence["tip_mm"], color=c_pers, lw=1.1, label="Persistence")
    _band(ax, s, np.array([v["tip_mm"] for v in validation]), c_gru, f"GRU ({len(validation)} seeds)")
    ax.axvline(horizon * dt, color="0.6", ls=":", lw=0.8)
    for t in map(float, validation[0]["at_s_mm"]):  # the report horizons
        k = round(t / dt) - 1
        ax.plot([s[k]] * len(validation), [v["tip_mm"][k] for v in validation], "o", ms=2.5, color=c_gru)
    ax.set_xlabel("Horizon (s)")
    ax.set_ylabel("Validation tip error (mm)")
    ax.set_xlim(0, s[-1] + dt)  # one step of margin
    ax.set_ylim(0, None)
    style.panel_label(ax, "a")

    per = gate["per_tau"]
    tau = np.array([p["tau"] for p in per])
    seeds = sorted(per[0]["v_pred"])
    tr = gate["trials"]
    ttau = np.array([t["tau"] for t in tr])
    for ax, meas, pred, scale, ylabel, letter in (
        (axes[1], "v_meas", "v_pred", 1.0, "Peak tip speed (m/s)", "b"),
        (
            axes[2],
            "travel_meas_m",
            "travel_pred_m",
            1e3,
            f"Tip travel, hold to S1 + {gate['window']['after_s1_s']:g} s (mm)",
            "c",
        ),
    ):
        ax.scatter(ttau, [t[meas] * scale for t in tr], s=6, color=c_meas, lw=0, alpha=0.45)
        ax.plot(tau, [p[meas] * scale for p in per], color=c_meas, lw=1.1, marker="o", ms=2.5, label="Measured")
        _band(ax, tau, np.array([[p[pred][k] * scale for p in per] for k in seeds]), c_gru, "Predicted (GRU)")
        ax.set_xlabel(r"S1 delay $\tau$ (s)")
        ax.set_ylabel(ylabel)
        style.panel_label(ax, letter)
    # One legend, in (a)'s empty corner: the GRU is the same colour in every panel, and inside
    # (b, c) the data of some sweeps would run under it.
    h, lab = axes[0].get_legend_handles_labels()
    hm, lm = axes[1].get_legend_handles_labels()
    axes[0].legend(h + hm[:1], lab + ["Measured (b, c)"], frameon=False, loc="upper left")
    style.save(fig, pdf, png)
