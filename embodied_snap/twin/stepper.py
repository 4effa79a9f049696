"""The simulated rig as the servo bus sees it: a stepping object that takes goals and advances in
time, returning present position and current; the arm's poses at the end of the trial.

This is the one coupling between the virtual Dynamixel bus (vbus.py) and the simulated rig. Today
the present position is an open-loop function of the goal (servo.py: the gearbox is not
backdrivable), so `advance` integrates the servo model step by step as goals arrive in wall-clock
time, and `finish` runs the arm's physics (sim.run: fold latch, cup seal on the target block) on
the present positions it produced, at the twin's step dt. A servo model whose position loop lives
inside the physics step changes `advance` and `finish` only; the bus does not change.
"""

from __future__ import annotations

import numpy as np

from . import servo as SV
from . import sim


class Stepper:
    def __init__(self, arm: dict, servo: dict, dt: float, latch: dict, target: dict | None = None,
                 seal: dict | None = None, rng: np.random.Generator | None = None):
        self.arm, self.dt, self.latch, self.target, self.seal = arm, dt, latch, target, seal
        self.rate = np.minimum(np.asarray(servo["rate"], float), SV.RATE_RATED)
        self.a = dt / np.asarray(servo["tau"], float)
        self.w = np.zeros(9)  # present position, ticks (float)
        self.goal = np.zeros(9)
        self.moving = np.zeros(9)
        self.powered = np.zeros(9, bool)  # torque enabled: without it the gearbox holds the shaft
        self.t = 0.0
        self.rows: list[np.ndarray] = []  # present positions, one row per physics step
        self.rng = rng or np.random.default_rng(0)

    def advance(self, t: float) -> None:
        """Integrate the servos from self.t to t (s) at dt with the goals set now."""
        n = int((t - self.t) / self.dt)
        step = self.rate * self.dt
        for _ in range(max(n, 0)):
            d = np.where(self.powered, np.clip((self.goal - self.w) * self.a, -step, step), 0.0)
            self.w = self.w + d
            self.rows.append(self.w.copy())
        if n > 0:
            self.moving = (np.abs(d) > 0.2 * step).astype(float)
            self.t += n * self.dt

    def set_goal(self, i: int, goal: float) -> None:
        self.goal[i] = goal

    def set_torque(self, i: int, on: bool) -> None:
        self.powered[i] = on
        if not on:
            self.goal[i] = self.w[i]

    def stop(self, i: int) -> None:
        """Hold where it is (the watchdog fired)."""
        self.goal[i] = self.w[i]

    def present(self) -> np.ndarray:
        return self.w.copy()

    def current_ma(self) -> np.ndarray:
        return SV.MA_IDLE * self.powered + 40.0 * self.moving + self.rng.normal(0.0, 3.0, 9)

    def finish(self, until: float | None = None) -> tuple[sim.Trial, np.ndarray]:
        """The arm's physics on the present positions up to `until` (s; all if None): (trial, present (T, 9))."""
        rows = self.rows if until is None else self.rows[:max(2, int(until / self.dt))]
        present = np.asarray(rows) if rows else np.zeros((2, 9))
        return sim.run(self.arm, present, self.dt, self.latch, target=self.target, seal=self.seal), present
