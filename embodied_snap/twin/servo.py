"""Servo model: Dynamixel XM430-W350-R in extended position mode, as the arm sees it.

The gearbox is not backdrivable, so the present position is an open-loop function of the goal:
a first-order lag (time constant tau_s) whose rate is clipped at the no-load ceiling. That lets the
whole present-position trace be computed in numpy before the physics runs.
"""

from __future__ import annotations

import numpy as np

# tick/s: the simulated servos' own no-load ceiling (their hardware truth, paper III-A), not the
# protocol's rated speed, which the pipeline reads from config rig.rated_speed_tick_s.
RATE_RATED = 3140.0
TAU_NOMINAL = 0.03  # s, first-order time constant of a burst fit (paper III-A)
SPOOL_RADIUS = 15.8e-6 * 4096 / (2 * np.pi)  # m: 15.8 um/tick over 4096 ticks/rev
MA_PER_NM = 360.0  # mA per N m of output torque (XM430-W350 torque constant, approx.)
MA_IDLE = 15.0


def present_from_goal(goal: np.ndarray, dt: float, rate: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """goal: (T, 9) ticks sampled every dt. Returns present (T, 9) float ticks.

    w' = clip((goal - w)/tau, -rate, rate), integrated exactly enough at dt << tau (explicit
    Euler at 1 ms is 3% of tau). `rate` is per servo and never above the rated ceiling.
    """
    goal = np.asarray(goal, float)
    rate = np.minimum(np.asarray(rate, float), RATE_RATED)
    w = np.empty_like(goal)
    cur = goal[0].copy()
    a = dt / np.asarray(tau, float)
    step_max = rate * dt
    for i in range(goal.shape[0]):
        cur = cur + np.clip((goal[i] - cur) * a, -step_max, step_max)
        w[i] = cur
    return w


def current_ma(tension_n: np.ndarray, moving: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Motor current from cable tension (holding torque = T * spool radius) plus a running term."""
    cur = MA_IDLE + MA_PER_NM * tension_n * SPOOL_RADIUS + 40.0 * moving
    return cur + rng.normal(0.0, 3.0, size=np.shape(cur))
