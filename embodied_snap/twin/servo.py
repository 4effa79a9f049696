"""Servo model: Dynamixel XM430-W350-R in extended position mode, as the arm sees it.

Each servo is a position loop acting on its spool through the cable:
- the loop's unloaded response (the "shaft" it would reach with no load) is a first-order lag
  (time constant tau_s) whose rate is clipped at the no-load ceiling; computed in numpy before
  the physics runs (`present_from_goal`);
- inside the physics step the cable tension loads the loop: a proportional position loop holds a
  torque T * r_spool with an error of T * r_spool / K_LOOP ticks (`deflection`), so the present
  position is the unloaded one minus that deflection, and the cable's free length follows the
  present position (embodied_snap.twin.sim). The torque saturates at the stall torque: beyond it
  the non-backdrivable gearbox holds and the deflection grows no further.
- current: from the same torque (`current_ma`).

K_LOOP is what the datasheet and the default gains give, not fitted: the position P gain (control
table default 800, i.e. 800/128 = 6.25 PWM units per tick of error) saturates the PWM (885 = 100 %)
at 142 ticks of error, where the motor delivers its stall torque (4.1 N m at 12 V), so
K_LOOP = 4.1 N m / 142 ticks = 0.029 N m/tick: 10 N of cable tension deflects it by 3.6 ticks.
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
STALL_NM = 4.1  # XM430-W350-R stall torque at 12 V (datasheet)
P_GAIN = 800.0  # Position P Gain, control-table default (KPP = P_GAIN / 128 PWM units per tick)
PWM_LIMIT = 885.0  # PWM limit, control-table default (100 %)
K_LOOP = STALL_NM * (P_GAIN / 128.0) / PWM_LIMIT  # N m per tick of position error (0.029)


def present_from_goal(goal: np.ndarray, dt: float, rate: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Unloaded loop response. goal: (T, 9) ticks sampled every dt. Returns (T, 9) float ticks.

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


def deflection(tension_n: np.ndarray) -> np.ndarray:
    """Position error (ticks, toward paying out) of the P loop holding cable tension T (N >= 0):
    T r / K_LOOP, saturating at the stall torque (the gearbox holds beyond it)."""
    return np.minimum(np.asarray(tension_n) * SPOOL_RADIUS, STALL_NM) / K_LOOP


def current_ma(tension_n: np.ndarray, moving: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Motor current from the loop's torque (T * spool radius, up to stall) plus a running term."""
    cur = MA_IDLE + MA_PER_NM * np.minimum(tension_n * SPOOL_RADIUS, STALL_NM) + 40.0 * moving
    return cur + rng.normal(0.0, 3.0, size=np.shape(cur))
