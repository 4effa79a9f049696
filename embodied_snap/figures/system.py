"""Figure 1: the system. (a) the arm as the simulated rig builds it (a rendered PNG), (b) the snap
primitive on one recorded strike: the nine servo goals and the three section bends over time with
the preload and the S3, S2, S1 releases the recording labels, (c) the shared policy: one network
per section (the same weights) and the selected policy's commands for one evaluation target."""

from __future__ import annotations

from dataclasses import dataclass

import matplotlib.image as mpimg
import numpy as np
import pandas as pd

from ..characterize.mocap import section_bends
from ..policy.networks import ACTIONS, ARCHS, n_params
from .style import PALETTE, TEXT_WIDTH_IN, plt, save, setup

# The releases of the primitive, as the recording labels them (docs/data.md), in time order.
EVENTS = (("t_preload", "preload"), ("t_slack", "S3 release"), ("t_s2", "S2 release"), ("t_s1", "S1 release"))
# What each section's copy of the shared network commands (policy/networks.py: section 1 gives
# rho1, dphi, tau; section 2 rho2; section 3 rho3, s3).
SECTION_OUTPUTS = (("rho1", "dphi", "tau"), ("rho2",), ("rho3", "s3"))
UNITS = dict(rho1="ticks", rho2="ticks", rho3="ticks", s3="ticks", dphi="deg", tau="s")
DIGITS = dict(dphi=1, tau=3)


def example_target(ev: pd.DataFrame) -> pd.Series:
    """The evaluation target whose closest approach is the median one (ties: the first)."""
    ev = ev.sort_values(["miss_m", "target_id"]).reset_index(drop=True)
    return ev.iloc[(len(ev) - 1) // 2]


def _commands(row: pd.Series) -> dict:
    col = dict(dphi="dphi_deg", tau="tau_s")
    return {a: float(row[col.get(a, a)]) for a in ACTIONS}


@dataclass(frozen=True)
class RecordedStrike:
    """One recorded group, as characterize.load.group reads it."""

    mocap: pd.DataFrame  # the tracked bodies
    servo: pd.DataFrame  # the servo log on the capture clock
    meta: dict  # the group's meta.json (group_id, labels)


def plot_system(render_png, strike: RecordedStrike, selected: dict, ev: pd.DataFrame, pdf, png, *,
                max_gap_s: float) -> dict:
    """Draw Fig. 1 (mocap dropouts up to max_gap_s bridged) from the arm's render (None with a real
    rig), one recorded strike, the selected policy (summary's `selected`) and its evaluation `ev`;
    returns what it shows (the group, the target and its commands)."""
    mocap, servo, meta = strike.mocap, strike.servo, strike.meta
    setup()
    fig = plt.figure(figsize=(TEXT_WIDTH_IN, 3.2))
    gs = fig.add_gridspec(2, 3, width_ratios=[0.7, 1.5, 1.3], hspace=0.18, wspace=0.3,
                          left=0.01, right=0.99, top=0.9, bottom=0.13)
    # (a)
    ax = fig.add_subplot(gs[:, 0])
    lab = meta.get("labels", {})
    if render_png is not None:
        img = mpimg.imread(render_png)
        ink = np.argwhere((img[..., :3] < 0.95).any(-1))  # crop the white margin around the arm
        (r0, c0), (r1, c1) = ink.min(0), ink.max(0)
        pad = 20
        ax.imshow(img[max(r0 - pad, 0) : r1 + pad, max(c0 - pad, 0) : c1 + pad])
        ax.set_axis_off()
        ax.set_title("(a) arm (twin model)", loc="left")
    else:  # a real rig: the tracked bodies of the strike when the S3 release starts
        k = int(np.argmin(np.abs(mocap.t.to_numpy() - float(lab.get("t_slack", mocap.t.iloc[0])))))
        pts = np.array([[mocap[f"{b}_{c}"].iloc[k] for c in "xy"] for b in ("base", "s1", "s2", "tip")])
        for s in range(3):
            ax.plot(pts[s : s + 2, 0], pts[s : s + 2, 1], color=PALETTE[s], lw=3, marker="o", ms=3)
        ax.set_aspect("equal")
        ax.set_axis_off()
        ax.set_title("(a) arm, tracked", loc="left")
    # (b)
    t0 = float(lab.get("t_preload", 0.0))
    t1 = float(lab.get("t_s1", servo.t.max())) + 0.8
    logged = servo[(servo.t >= t0 - 0.3) & (servo.t <= t1)]
    ax1 = fig.add_subplot(gs[0, 1])
    for k in range(1, 10):
        ax1.plot(logged.t - t0, logged[f"goal_{k}"], color=PALETTE[(k - 1) // 3], lw=0.8,
                 alpha=0.5 + 0.25 * ((k - 1) % 3))
    ax1.set_ylabel("servo goal (ticks)")
    ax1.set_title(f"(b) primitive, recorded strike {meta['group_id']}", loc="left")
    ax1.tick_params(labelbottom=False)
    tracked = mocap[(mocap.t >= t0 - 0.3) & (mocap.t <= t1)]
    theta, _ = section_bends(tracked, max_gap_s)
    ax2 = fig.add_subplot(gs[1, 1], sharex=ax1)
    for i in range(3):
        ax2.plot(tracked.t - t0, np.rad2deg(theta[:, i]), color=PALETTE[i], lw=1, label=f"S{i + 1}")
    ax2.set_ylabel("bend (deg)")
    ax2.set_xlabel("time from preload (s)")
    ax2.legend(loc="upper right", frameon=False, ncol=3, borderaxespad=0.1)
    for k, name in EVENTS:
        if k in lab:
            for a in (ax1, ax2):
                a.axvline(float(lab[k]) - t0, color="0.4", lw=0.6, ls="--")
            ax1.text(float(lab[k]) - t0, 1.0, " " + name, transform=ax1.get_xaxis_transform(), rotation=90,
                     va="top", ha="left", fontsize=6, color="0.3")
    # (c)
    row = example_target(ev)
    cmd = _commands(row)
    axc = fig.add_subplot(gs[:, 2])
    axc.set_xlim(0, 10)
    axc.set_ylim(0, 10)
    axc.set_axis_off()
    (n_in, width), n_out = ARCHS["shared"][0][0][::-1], ARCHS["shared"][0][-1][0]
    axc.set_title(f"(c) shared policy, seed {selected['seed']} ({n_params('shared')} params)", loc="left")
    axc.text(0.0, 9.6, f"target {row['target_id']}: d = {row['d_m']:.2f} m, e = {row['e_m']:.2f} m,\n"
             f"bearing {row['bearing_deg']:.0f} deg", fontsize=6, va="top")
    for i, outs in enumerate(SECTION_OUTPUTS):
        y = 7.3 - 2.9 * i
        axc.text(0.0, y, f"g, e{i + 1}", fontsize=6, va="center")
        axc.add_patch(plt.Rectangle((2.2, y - 0.9), 2.6, 1.8, fc=PALETTE[i], alpha=0.25, ec=PALETTE[i]))
        axc.text(3.5, y, f"S{i + 1}\n{n_in}-{width}-{width}-{n_out}", ha="center", va="center", fontsize=6)
        axc.annotate("", (2.2, y), (1.3, y), arrowprops=dict(arrowstyle="->", lw=0.6))
        axc.annotate("", (5.6, y), (4.8, y), arrowprops=dict(arrowstyle="->", lw=0.6))
        txt = "\n".join(f"{a} = {cmd[a]:.{DIGITS.get(a, 0)}f} {UNITS[a]}" for a in outs)
        axc.text(5.7, y, txt, va="center", fontsize=6)
    axc.text(0.0, 0.4, f"same weights in every section;\nclosest approach {row['miss_m'] * 1e3:.0f} mm",
             fontsize=6, color="0.3", va="top")
    save(fig, pdf, png)
    return dict(group=meta["group_id"], target=str(row["target_id"]), commands=cmd, seed=int(selected["seed"]))
