"""The simulated rig as the servo bus sees it: goals and torque switches in, present position and
current out, the arm's physics stepped live.

This is the one coupling between the virtual Dynamixel bus (vbus.py) and the simulated rig. The bus
hands over what it heard with its trial-clock time (`set_goal`, `set_torque`, `stop`); `advance(t)`
steps the arm to t, one `mj_step` per dt (sim.Arm: the servo position loops inside the physics step,
the fold latch, the cup seal, the block on its support), applying each of those at its time. Each
servo's unloaded loop response (the "shaft") follows its goal as in servo.present_from_goal, and
stands still while torque is off or after its watchdog stopped it (the gearbox holds). Present
position and current come from the simulation: the shaft minus the loop's deflection under the cable
tension, and the current of that tension (servo.py). `present`/`current_ma` read the last step, so
the bus may answer from another thread while `advance` runs. `wrench` (optional): external forces
on the mount and the proximal segment, as sim.run's (MuJoCo xfrc_applied), asked for each step.
"""

from __future__ import annotations

import threading

import numpy as np

from . import model as M
from . import servo as SV
from . import sim


class Stepper:
    def __init__(self, arm: dict, servo: dict, dt: float, latch: dict, scene: sim.Scene = sim.NO_TARGET,
                 rng: np.random.Generator | None = None, wrench=None):
        """scene: the target, if any (sim.Scene). wrench: None, or wrench(t) -> {"mount": (3,),
        "proximal": (3,)} N in the arm frame (or None: no force) for the step that ends at trial time t."""
        self.dt = dt
        self.rate = np.minimum(np.asarray(servo["rate"], float), SV.RATE_RATED)
        self.a = dt / np.asarray(servo["tau"], float)
        self.sim = sim.Arm(arm, dt, latch, scene=scene, rate=self.rate, n=8192)
        self.w = np.zeros(9)  # the loops' unloaded response (shaft), ticks (float)
        self.goal = np.zeros(9)
        self.moving = np.zeros(9)
        self.powered = np.zeros(9, bool)  # torque enabled: without it the gearbox holds the shaft
        self.t = 0.0
        self.rows: list[np.ndarray] = []  # the shafts, one row per physics step
        self._present = np.zeros(9)
        self._tension = np.zeros(9)
        self._events: list[tuple[float, str, int, float]] = []  # (t, what, servo, value), appended by the bus
        self._ev_lock = threading.Lock()
        self.rng = rng or np.random.default_rng(0)
        self.wrench = wrench
        if wrench is not None:
            import mujoco

            m = self.sim.m
            self._pushed = [(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name), key)
                            for name, key in (("base", "mount"), (M.PROXIMAL, "proximal"))]

    def _at(self, t: float | None, what: str, i: int, value: float = 0.0) -> None:
        with self._ev_lock:
            self._events.append((self.t if t is None else t, what, i, value))

    def _apply_due(self) -> None:
        with self._ev_lock:
            due = [e for e in self._events if e[0] <= self.t + 1e-12]
            self._events = [e for e in self._events if e[0] > self.t + 1e-12]
        for _, what, i, value in sorted(due, key=lambda e: e[0]):
            if what == "goal":
                self.goal[i] = value
            elif what == "torque":
                self.powered[i] = bool(value)
                if not value:
                    self.goal[i] = self.w[i]
            elif what == "stop":
                self.goal[i] = self.w[i]

    def advance(self, t: float) -> None:
        """Step the arm from self.t to t (s), applying what the bus heard at its time."""
        step = self.rate * self.dt
        for _ in range(max(int((t - self.t) / self.dt + 1e-9), 0)):
            self._apply_due()
            d = np.where(self.powered, np.clip((self.goal - self.w) * self.a, -step, step), 0.0)
            self.w = self.w + d
            self.rows.append(self.w)
            if self.wrench is not None:
                self._push(self.t + self.dt)
            self._present = self.sim.step(self.w).copy()
            self._tension = -self.sim.force[self.sim.i - 1]
            self.moving = (np.abs(d) > 0.2 * step).astype(float)
            self.t += self.dt

    def _push(self, t: float) -> None:
        f = self.wrench(t)
        for bid, key in self._pushed:
            self.sim.d.xfrc_applied[bid, :3] = 0.0 if f is None else f[key]

    def set_goal(self, i: int, goal: float, t: float | None = None) -> None:
        self._at(t, "goal", i, goal)

    def set_torque(self, i: int, on: bool, t: float | None = None) -> None:
        self._at(t, "torque", i, float(on))

    def stop(self, i: int, t: float | None = None) -> None:
        """Hold where it is from t (the watchdog fired)."""
        self._at(t, "stop", i)

    def present(self) -> np.ndarray:
        return self._present.copy()

    def current_ma(self) -> np.ndarray:
        """Current of the loop's torque under the cable tension; about zero with torque off."""
        cur = SV.current_ma(self._tension, self.moving, self.rng)
        return np.where(self.powered, cur, self.rng.normal(0.0, 3.0, 9))

    def finish(self, until: float | None = None) -> tuple[sim.Trial, np.ndarray]:
        """The trial up to `until` (s; all stepped so far if None), stepped on to it if the bus stopped
        short: (trial, present (T, 9))."""
        if until is not None and self.t < until:
            self.advance(until)
        n = None if until is None else max(2, int(until / self.dt + 1e-9))
        if self.sim.i < 2:
            self.advance(2 * self.dt)
        tr = self.sim.trial(n)
        return tr, tr.present
