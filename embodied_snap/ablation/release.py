"""The release-rule ablation (paper IV-B last paragraph, V-B "Event triggers", Fig. 6a-b): the
selected shared policy's loading and aim held fixed, S1 released by the learned target-only tau,
a fixed clock, or an event of the S1-held rollout plus an offset delta fitted on other targets;
and two references, the per-family clock and the per-start oracle.

Every rule's outcome is read from one table per target set: the outcome of each admissible
release step (triggers module docstring), so fitting offsets and comparing rules costs one batch
of rollouts per set plus the S1-held batch for the event times.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import kinematics as KM
from . import triggers as TR
from .rollouts import OUTCOMES, held_rollout, release_table

EVENT_RULES = ("s1_rate", "tip_speed", "s2_peak")
RULES = ("target_only", "clock", *EVENT_RULES)
REFERENCES = ("family_clock", "oracle")


def events(sim, act: dict, T, proto: dict) -> dict:
    """Event times (s) of the three triggers on the S1-held rollout of each target.
    proto: dt, anchor_s, timing, s1_rate_deg_s, tip_speed_mps, hanging_axis."""
    dt, anchor, timing = proto["dt"], proto["anchor_s"], proto["timing"]
    last = int(TR.release_step(timing[1], anchor, dt))
    x = held_rollout(sim, act, steps=last)["x"]
    th = KM.bend_angles(x, np.asarray(proto["hanging_axis"]))
    rate = KM.rates(th, dt)
    k = TR.event_steps(rate[..., 0], rate[..., 1], KM.tip_speed(x, dt), last, proto["s1_rate_deg_s"],
                       proto["tip_speed_mps"])
    return {r: anchor + dt * v for r, v in k.items()}


def table(sim, act: dict, T, proto: dict) -> tuple[np.ndarray, dict]:
    steps, times = TR.admissible_steps(proto["timing"], proto["anchor_s"], proto["dt"])
    return steps, release_table(sim, act, T, times)


def fit_offsets(t_e: dict, steps, tab: dict, deltas, proto: dict, objective: str = "reward") -> dict:
    """The offset of each event rule maximising the mean `objective` on these (offset) targets."""
    out = {}
    for r in EVENT_RULES:
        d, score = TR.fit_offset(t_e[r], tab[objective], steps, np.asarray(deltas), proto["timing"],
                                 proto["anchor_s"], proto["dt"])
        out[r] = dict(delta_s=d, score=score.tolist())
    return out


def release_times(tau: np.ndarray, t_e: dict, offsets: dict, clock_s: float) -> dict:
    """Unprojected release time of each rule."""
    t = {"target_only": np.asarray(tau, float), "clock": np.full(len(tau), clock_s)}
    for r in EVENT_RULES:
        t[r] = t_e[r] + offsets[r]["delta_s"]
    return t


def compare(T, steps, tab: dict, t_raw: dict, proto: dict) -> pd.DataFrame:
    """One row per (rule, target): release time, whether it was projected, outcomes. The
    references pick their step from the table itself: per family the one step with the best mean
    reward over the family's starts, per start the best step."""
    dt, anchor, timing = proto["dt"], proto["anchor_s"], proto["timing"]
    fam = T.df["family"].to_numpy()
    N, rows = len(T), []
    col = {}
    for r, t in t_raw.items():
        col[r] = np.searchsorted(steps, TR.release_step(TR.project(t, timing), anchor, dt))
    fc = np.empty(N, int)
    for f in np.unique(fam):
        sel = fam == f
        fc[sel] = int(np.argmax(tab["reward"][sel].mean(0)))
    col["family_clock"], col["oracle"] = fc, tab["reward"].argmax(1)
    for r, c in col.items():
        d = {"rule": r, "target_id": T.df["target_id"], "family": fam, "release_step": steps[c],
             "t_raw_s": t_raw[r] if r in t_raw else np.nan,
             "at_bound": TR.at_bound(t_raw[r], timing) if r in t_raw else False}
        d.update({k: tab[k][np.arange(N), c] for k in OUTCOMES})
        rows.append(pd.DataFrame(d))
    return pd.concat(rows, ignore_index=True)
