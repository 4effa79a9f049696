"""Release rules (paper IV-B last paragraph, V-B "Event triggers"): when S1 lets go.

Time is the simulator's clock (policy.simulate): 0 is the start of the S2 release, the rollout's
step k lies at anchor + k dt. A rule's release time is projected onto the timing set T (Eq. 8).
The simulator releases S1 at the first goal frame at or after t_rel and scores closest approach
from step ceil((t_rel - anchor) / dt) on, so every release time maps to one release step:
outcomes tabulated per release step are exactly the outcomes of every rule.

Event times come from a rollout with S1 held (no release), measured causally (backward
differences) from step 1 up to the last admissible release step; an event that never fires is
placed at that last step (then projected, like any other).
"""

from __future__ import annotations

import numpy as np


def project(t, timing) -> np.ndarray:
    """Pi_T: the release time clipped to the timing set (Eq. 8)."""
    return np.clip(t, *timing)


def at_bound(t, timing) -> np.ndarray:
    """Releases the projection moved (t outside T): they sit on a timing bound."""
    t = np.asarray(t, float)
    return (t < timing[0]) | (t > timing[1])


def release_step(t_rel, anchor: float, dt: float) -> np.ndarray:
    """The rollout step the simulator releases S1 at (policy.simulate.Simulator.run's k_s1)."""
    return np.ceil((np.asarray(t_rel, float) - anchor) / dt).astype(int)


def admissible_steps(timing, anchor: float, dt: float, fine: int = 1000) -> tuple[np.ndarray, np.ndarray]:
    """Every release step some t in T maps to, and one release time inside each step (a time in
    the middle of the step's interval, away from the rounding edges)."""
    t = np.linspace(*timing, fine)
    k = release_step(t, anchor, dt)
    steps = np.unique(k)
    rep = np.array([np.median(t[k == s]) for s in steps])
    return steps, rep


def first_crossing(y: np.ndarray, threshold: float, last: int) -> np.ndarray:
    """First step in 1..last at which y (N, T) reaches threshold; `last` where it never does."""
    hit = y[:, 1:last + 1] >= threshold
    return np.where(hit.any(1), hit.argmax(1) + 1, last)


def peak(y: np.ndarray, last: int) -> np.ndarray:
    """Step of the maximum of y (N, T) in 1..last."""
    return y[:, 1:last + 1].argmax(1) + 1


def event_steps(s1_rate, s2_rate, tip_speed, last: int, s1_deg_s: float, tip_mps: float) -> dict:
    """Event step of each trigger from the S1-held rollout's S1 and S2 bend rates (deg/s) and tip
    speed (m/s), all (N, T): local S1 rate crossing, distal tip speed crossing, S2 peak rate."""
    return {"s1_rate": first_crossing(s1_rate, s1_deg_s, last),
            "tip_speed": first_crossing(tip_speed, tip_mps, last),
            "s2_peak": peak(s2_rate, last)}


def fit_offset(t_e: np.ndarray, table: np.ndarray, steps: np.ndarray, deltas: np.ndarray, timing,
               anchor: float, dt: float) -> tuple[float, np.ndarray]:
    """The offset delta maximising the mean of table (N, len(steps)) (a per-target outcome per
    release step) at t_rel = Pi_T(t_e + delta); ties go to the smallest |delta|. Also the mean per
    delta."""
    score = np.array([lookup(table, steps, release_step(project(t_e + d, timing), anchor, dt)).mean()
                      for d in deltas])
    best = np.flatnonzero(score >= score.max() - 1e-12)
    return float(deltas[best[np.argmin(np.abs(deltas[best]))]]), score


def lookup(table: np.ndarray, steps: np.ndarray, k: np.ndarray) -> np.ndarray:
    """table[i, column of step k_i] for every target i."""
    col = np.searchsorted(steps, k)
    if (col >= len(steps)).any() or (steps[np.minimum(col, len(steps) - 1)] != k).any():
        raise ValueError("a release step outside the tabulated steps")
    return table[np.arange(len(table)), col]
