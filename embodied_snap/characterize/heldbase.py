"""Held-base trials (paper V-C): which causal signal times the event (docs/characterize.md).

Each detector sees only the past: it fires at the first sample after it is armed where its signal
leaves a lagged reference by more than its threshold; a detection counts if it fires within window_s
of the event (100 ms; config characterize.heldbase holds it and the thresholds). Detectors:
- base: the tracked mount's displacement (mm);
- neighbour: the displacement of the next tracked body down the arm (distal end of S1, mm);
- servo residual: S1-S3 servo present position minus the fitted first-order servo model (ticks);
- best clock: a fixed time after the arming moment, the one constant that catches most events.

Two readings of "the event" (READINGS). The project's (READING, decided before it was measured, for
the reason docs/characterize.md gives): the paper's passage sits in the release-timing subsection and
speaks of the mechanical wave, so the event is the trial's snap: the first time after the S2 release
starts (t_s2) that the tip's speed reaches the attachment threshold, the rule of the
snap_speed_event label; every detector is armed at t_s2, as a release trigger would be. The other,
kept for comparison: the event is the hand's push on the mount (base_event_t), with detectors armed
from the preload on.
"""

from __future__ import annotations

import numpy as np

from ..rawformat import GOAL_INTERVAL, goal_timing
from . import mocap as M
from .servo import DT, goal_on_grid, simulate

REF_LAG_S = (0.5, 0.25)  # the reference is the mean over [t - 0.5 s, t - 0.25 s]: causal, slow


# reading -> the label that arms its detectors and starts its clock
READINGS = {"snap": "t_s2", "push": "t_preload"}
READING = "snap"


def snap_time(t, v, t_arm: float, speed_mps: float) -> float:
    """First time at or after t_arm that the tip speed v reaches speed_mps (NaN: no snap)."""
    hit = (t >= t_arm) & (v >= speed_mps)
    return float(t[np.argmax(hit)]) if hit.any() else float("nan")


def fire_time(t, x, thr, t_arm: float = -np.inf) -> float:
    """First time at or after t_arm that the displacement of x (n, d) from its lagged reference
    (mean over the window REF_LAG_S back) exceeds thr; the window mean comes from cumulative sums."""
    xs = M.smooth3(x)
    ok = ~np.isnan(xs).any(1)
    c = np.vstack([np.zeros(xs.shape[1]), np.cumsum(np.where(ok[:, None], xs, 0), 0)])
    n = np.concatenate([[0], np.cumsum(ok)])
    a = np.searchsorted(t, t - REF_LAG_S[0])
    b = np.searchsorted(t, t - REF_LAG_S[1], side="right")
    cnt = n[b] - n[a]
    ref = (c[b] - c[a]) / np.maximum(cnt, 1)[:, None]
    d = np.linalg.norm(xs - ref, axis=1)
    hit = ok & (cnt >= 3) & (d > thr) & (t >= t_arm)
    return float(t[np.argmax(hit)]) if hit.any() else float("nan")


def servo_residual(sv, rate, tau, servos=(1, 2, 3), timing=GOAL_INTERVAL) -> tuple[np.ndarray, np.ndarray]:
    """|present - model(goal)| of the given servos at the log times (max over servos); `timing`:
    the log's goal timing (rawformat.GOAL_TIMING)."""
    t = sv.t.to_numpy()
    grid = np.arange(0.0, t[-1] + DT, DT)
    idx = np.clip(np.round(t / DT).astype(int), 0, len(grid) - 1)
    res = []
    for j in servos:
        g = goal_on_grid(t, sv[f"goal_{j}"].to_numpy(float), grid, timing=timing)
        w = simulate(grid, g[None], np.array([sv[f"present_{j}"].iloc[0]], float), rate, tau)[0]
        res.append(np.abs(sv[f"present_{j}"].to_numpy(float) - w[idx]))
    return t, np.max(res, 0)


def trial(mc, sv, meta, servo_fit, thr, max_gap_s: float, snap_mps: float) -> dict:
    mc = M.on_grid(mc)  # smooth3 spans the same time at any capture rate
    t = mc.t.to_numpy()
    lab = meta["labels"]
    ts, res = servo_residual(sv, servo_fit["rate_tick_s"], servo_fit["tau_s"], timing=goal_timing(meta))
    t_s1 = lab.get("t_s1", np.nan)
    near = np.abs(ts - t_s1) <= 0.1
    base, s1 = (M.track(mc, b, max_gap_s=max_gap_s) * 1e3 for b in ("base", "s1"))
    events = dict(snap=snap_time(t, M.tip_speed(mc, max_gap_s), float(lab["t_s2"]), snap_mps),
                  push=float(lab["base_event_t"]))
    readings = {}
    for name, arm in READINGS.items():
        t0 = float(lab.get(arm, 0.0))
        fire = (res > thr["residual_ticks"]) & (ts >= t0)
        readings[name] = dict(event=events[name], t0=t0,
                              base=fire_time(t, base, thr["base_mm"], t0),
                              neighbour=fire_time(t, s1, thr["neighbour_mm"], t0),
                              residual=float(ts[np.argmax(fire)]) if fire.any() else float("nan"))
    return dict(readings=readings,
                residual_trigger_max=float(res[near].max()) if near.any() else float("nan"),
                residual_quiet_median=float(np.median(res[~near])))


def summarize(trials, window_s: float) -> dict:
    """The decided reading's rates at the top (what the claims read), every reading's beside them."""
    rd = {name: rates([x["readings"][name] for x in trials], window_s) for name in READINGS}
    return dict(rd[READING], reading=READING, armed_at=READINGS[READING],
                readings=rd,
                residual_trigger_ticks=float(np.nanmedian([x["residual_trigger_max"] for x in trials])),
                residual_quiet_ticks=float(np.nanmedian([x["residual_quiet_median"] for x in trials])),
                trials=trials)


def rates(rows, window_s: float) -> dict:
    """Share of trials each detector fires within window_s of the event, over the trials whose
    event was labelled; and the best clock (one delay after t0, chosen on these trials)."""
    rows = [x for x in rows if np.isfinite(x["event"])]
    ev = np.array([x["event"] for x in rows])

    def frac(tf):
        tf = np.asarray(tf, float)
        return float(np.mean(np.abs(tf - ev) <= window_s)) if len(ev) else float("nan")

    # The best clock: one constant delay after t0 (the arming moment), chosen on these trials.
    rel = ev - np.array([x["t0"] for x in rows])
    cands = np.arange(0.0, rel.max() + window_s, 0.01) if len(rel) else np.array([0.0])
    hits = [np.mean(np.abs(rel - c) <= window_s) for c in cands]
    c_best = float(cands[int(np.argmax(hits))])
    return dict(n=len(rows), window_s=window_s,
                fraction_within={k: frac([x[k] for x in rows]) for k in ("base", "neighbour", "residual")}
                | {"clock": float(max(hits)) if len(rel) else float("nan")},
                clock_delay_s=c_best)
