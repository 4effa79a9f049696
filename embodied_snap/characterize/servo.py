"""Servo rate (paper III-A): a first-order, rate-limited fit over all calibration bursts, and the
tendon-driven bend-rate ceilings of Eq. 2.

Model of one servo: dw/dt = clip((goal - w) / tau, -rate, rate). Both constants are fitted jointly
to every burst's logged present position (scipy least_squares), simulating each burst from its
logged goal program.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from ..rawformat import GOAL_INTERVAL, GOAL_ROW

DT = 0.001  # s, integration step of the model (servo log is ~100 Hz)


def simulate(t_grid, goal, w0, rate, tau):
    """Integrate the model on a grid. goal: (n_series, n_steps); w0: (n_series,)."""
    w = np.empty_like(goal)
    w[:, 0] = w0
    a = min(DT / tau, 1.0)
    for k in range(1, goal.shape[1]):
        step = np.clip(a * (goal[:, k - 1] - w[:, k - 1]), -rate * DT, rate * DT)
        w[:, k] = w[:, k - 1] + step
    return w


def goal_on_grid(t_log, goal_log, t_grid, t_changes=(), timing=GOAL_INTERVAL):
    """The commanded goal as a step function. A change is seen at the first log sample that shows
    it; it happened at a labelled command time if one lies in that log interval, otherwise, by the
    log's goal timing (rawformat.GOAL_TIMING), at the interval's midpoint ("interval") or at the
    row itself ("row": written in that row's cycle, just before its read)."""
    g = np.full(len(t_grid), goal_log[0], float)
    ch = np.flatnonzero(np.diff(goal_log) != 0) + 1
    for k in ch:
        lo, hi = t_log[k - 1], t_log[k]
        at = [c for c in t_changes if lo < c <= hi]
        tc = at[0] if at else hi if timing == GOAL_ROW else 0.5 * (lo + hi)
        g[t_grid >= tc] = goal_log[k]
    return g


def prepare(bursts):
    """bursts: list of dicts with t (log times), goal and present (n, 3 servos), t_changes, timing.
    Returns grid arrays for the fit: goal (m, n_steps), logged present, and the sampling index."""
    T = max(b["t"][-1] for b in bursts) + DT
    grid = np.arange(0.0, T, DT)
    G, W0, obs = [], [], []
    for b in bursts:
        idx = np.clip(np.round(b["t"] / DT).astype(int), 0, len(grid) - 1)
        for j in range(b["goal"].shape[1]):
            G.append(goal_on_grid(b["t"], b["goal"][:, j], grid, b.get("t_changes", ()),
                                  b.get("timing", GOAL_INTERVAL)))
            W0.append(b["present"][0, j])
            obs.append((len(G) - 1, idx, b["present"][:, j]))
    return grid, np.array(G), np.array(W0), obs


def fit(bursts, x0=(2500.0, 0.05)):
    """Joint least-squares fit of (max rate tick/s, time constant s) to all bursts."""
    grid, G, W0, obs = prepare(bursts)

    def resid(p):
        w = simulate(grid, G, W0, p[0], p[1])
        return np.concatenate([w[i, idx] - y for i, idx, y in obs])

    r = least_squares(resid, x0, bounds=([100.0, 0.002], [20000.0, 0.5]), x_scale=(1000.0, 0.01))
    res = resid(r.x)
    return dict(rate_tick_s=float(r.x[0]), tau_s=float(r.x[1]),
                rmse_ticks=float(np.sqrt(np.mean(res**2))), n_series=len(obs))


def _cumsum0(x):
    """Cumulative sums with a leading zero: the sum over samples [i, j) is c[j] - c[i]."""
    return np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, 0)])


RATE_WINDOW_S = 0.05  # s: about five ~100 Hz sync-reads, well inside a burst's saturated travel


def peak_rates(bursts, window_s: float = RATE_WINDOW_S):
    """Per burst, the largest |dw/dt| of its servos (tick/s): the least-squares slope of present
    position on log time over every window of `window_s` that starts at a sample. A difference
    of two samples divides by one jittered interval: on a live bus its timestamps are the
    client's, and the jitter alone reads above the rated speed."""
    out = []
    for b in bursts:
        t, w = b["t"] - b["t"][0], np.asarray(b["present"], float)
        St, Stt, Sw, Stw = _cumsum0(t), _cumsum0(t * t), _cumsum0(w), _cumsum0(t[:, None] * w)
        i = np.arange(len(t))
        j = np.searchsorted(t, t + window_s, side="right")  # window i covers samples [i, j)
        ok = j - i >= 3
        i, j = i[ok], j[ok]
        n = (j - i)[:, None]
        st, stt = (St[j] - St[i])[:, None], (Stt[j] - Stt[i])[:, None]
        slope = (n * (Stw[j] - Stw[i]) - st * (Sw[j] - Sw[i])) / (n * stt - st * st)
        out.append(float(np.abs(slope).max()))
    return np.array(out)


def ceilings(rated_tick_s: float, lever_ticks_per_rad) -> list[float]:
    """Eq. 2: the tendon-driven bend-rate ceiling of each section, rad/s."""
    return [rated_tick_s / d for d in lever_ticks_per_rad]
