"""One trial on the arm: servo goals in, body trajectories and observed events out.

The present positions are precomputed from the goals (servo.py); the physics is stepped in a
plain Python loop because two things depend on the state: the fold latch and the cup seal.

Fold latch (paper III-B: "the folded lattice retains a curled tip as a mechanical latch"): once
S3 has been curled past `engage_rad` and its curl starts to open by `catch_rad` (its cables were
slackened), the curled tip catches on the arm and the closed fold holds the whole arm's shape. It
is one equality constraint per joint, switched on (a stable latch; an explicit stiff spring is
not). While latched, the servos keep paying out and the cables go slack behind the held shape, so
the stored elastic energy is no longer metered by the servo rate. The fold creeps (its held angles
in S2, S3 relax toward straight with time constant `creep_s`: stress relaxation of the TPU). It
is clamped shut by the S1 cables and pops when the most wound S1 cable hangs `open_m` slack (or,
as a fuse, when it carries more than `break_nm`). After the pop each section recoils freely until
a cable that still has take-up catches it.

Cup seal: a cup that reaches the target face with lateral overlap, a gap within `seal_gap_m`,
normal speed above `speed_mps` and tilt below `tilt_deg` seals (a ball joint to the block);
anything else bounces off the block (MuJoCo contact).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..quat import to_matrix as quat_to_mat
from . import model as M
from . import servo as SV

CUP_R = 0.02  # m, cup collision radius (simulated hardware, not a protocol value)
CHECK_S = 0.004  # s between latch / seal checks (independent of dt)
RATE_CHECKS = 5  # the curl's opening rate at the catch is measured over this many checks (20 ms)


@dataclass
class Trial:
    t: np.ndarray  # (T,) s, every physics step
    pos: np.ndarray  # (T, 3, 3) positions of s1, s2, tip (S3 distal end)
    quat: np.ndarray  # (T, 3, 4) orientations of those bodies (w, x, y, z)
    cup: np.ndarray  # (T, 3) cup face (end-effector tip) position
    tension: np.ndarray  # (T, 9) cable tensions, N (>= 0)
    present: np.ndarray  # (T, 9) servo present positions, ticks (unloaded loop minus deflection)
    base: np.ndarray  # (T, 3) mount position (arm frame; 0 at rest)
    events: dict = field(default_factory=dict)
    target_pos: np.ndarray | None = None  # (T, 3) the free block (deployment), else None
    target_quat: np.ndarray | None = None  # (T, 4)


@dataclass(frozen=True)
class Scene:
    """What the cup can meet in a trial. The default: nothing (a trial without a target)."""

    target: dict | None = None  # the block: pos, quat, R, normal, half (acquire.place_target, deployment.block_at)
    seal: dict | None = None  # the cup seal's thresholds (truth.SEAL); read only with a target
    block: dict | None = None  # deployment: the target is a free block on its support (truth.BLOCK), else fixed


NO_TARGET = Scene()  # a trial without a target


def _ids(m):
    import mujoco

    segs = M.seg_names()
    last = {s: max(i for ss, i, _ in segs if ss == s) for s in (1, 2, 3)}
    bodies = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"seg{s}_{last[s]}") for s in (1, 2, 3)]
    sites = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, n) for n in M.BODY_NAMES]
    cup = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "cup")
    mount = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "mount")
    # dof addresses per section
    dofs = {s: [] for s in (1, 2, 3, 4)}
    for s, _i, name in segs:
        for ax in "zx":
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_{ax}")
            dofs[s].append(int(m.jnt_dofadr[j]))
    return bodies, sites, cup, mount, {s: np.array(v) for s, v in dofs.items()}


def section_bend(q: np.ndarray, dofs: dict, s: int) -> float:
    """Bend magnitude of section s in rad (small-angle sum of its joints' bend vectors)."""
    qq = q[dofs[s]].reshape(-1, 2)
    return float(np.hypot(qq[:, 0].sum(), qq[:, 1].sum()))


class Arm:
    """One trial's physics, one step at a time (`step`), for sim.run (a precomputed shaft) and the
    deployment's stepper (shafts that follow goals as they arrive): the servo loops, the fold latch
    and the cup seal. `scene.block` (deployment only; the model was built with p["block_mass"]): the
    target is a free body held on its support by a weld that releases once the seal pulls it with
    more than `release_n`; the seal lets go when it carries more than `hold_n` (both averaged over
    a check interval). `n`: the steps the buffers first hold (they grow). m, d: MuJoCo's model and
    data, by MuJoCo's own names."""

    def __init__(self, p: dict, dt: float, latch: dict, scene: Scene = NO_TARGET, rate: np.ndarray | None = None,
                 n: int = 1024):
        import mujoco

        target, block = scene.target, scene.block
        self.mj = mujoco
        self.m = m = M.build(p, dt)
        self.d = d = mujoco.MjData(m)
        self.dt, self.latch, self.target, self.seal, self.block = dt, latch, target, scene.seal, block
        self.bodies, self.sites, self.cup_site, self.mount_site, dofs = _ids(m)
        self.dofs = dofs
        self.defl = np.zeros(9)
        self.rate_step = (SV.RATE_RATED if rate is None else np.minimum(np.asarray(rate, float), SV.RATE_RATED)) * dt
        # every step, whole arrays are copied (no fancy indexing in the loop); selected afterwards
        self.present = np.empty((n, 9))
        self.site_buf = np.empty((n, m.nsite, 3))
        self.quat_buf = np.empty((n, m.nbody, 4))
        self.force = np.empty((n, 9))
        # the fold latch locks every arm joint (equalities in model.py order, S1 first); only the
        # distal fold (S2, S3) creeps
        self.eq_ids = np.arange(sum(len(dofs[s]) for s in (1, 2, 3)))
        self.creep_ids = self.eq_ids[len(dofs[1]) :]
        self.latch_dofs = np.concatenate([dofs[1], dofs[2], dofs[3]])
        self.eq_qadr = np.array([m.jnt_qposadr[m.eq_obj1id[e]] for e in self.eq_ids])
        self.every = max(1, int(round(CHECK_S / dt)))  # latch and seal are checked every CHECK_S
        self.ev = dict(latch_on=None, latch_off=None, latch_cause=None, sealed=None, contact=None)
        self.latched = False
        self.b3_hist = []
        self.relax = self.every * dt / latch["creep_s"]
        self.clamp = 0
        self.b3max = 0.0
        self.sealed = False
        self.i = 0
        if target is not None:
            self.tb = tb = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "target")
            if block is None:
                m.body_pos[tb] = target["pos"]
                m.body_quat[tb] = target["quat"]
                d.mocap_pos[0] = target["pos"]
                d.mocap_quat[0] = target["quat"]
            else:  # a free block on its support (a weld to the world at its placement)
                adr = m.jnt_qposadr[m.body_jntadr[tb]]
                d.qpos[adr : adr + 3] = target["pos"]
                d.qpos[adr + 3 : adr + 7] = target["quat"]
                self.support = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, "support")
                m.eq_data[self.support, 0:3] = target["pos"]  # anchor on the world
                m.eq_data[self.support, 3:6] = 0.0  # the block's origin
                q = np.asarray(target["quat"], float)
                m.eq_data[self.support, 6:10] = [q[0], -q[1], -q[2], -q[3]]
                d.eq_active[self.support] = 1
                self.tpos_buf = np.empty((n, 3))
                self.tquat_buf = np.empty((n, 4))
                self.pull = []  # the seal's force on the block, N, since the last check
                self.ev.update(released=None, seal_lost=None)
            self.normal = np.asarray(target["normal"], float)  # face normal in block coordinates
            self.half = np.asarray(target["half"], float)
            self.R = np.asarray(target["R"], float)  # columns: block axes in the arm frame
            self.tpos = np.asarray(target["pos"], float)
            self.face = float(self.half @ np.abs(self.normal))
            self.seal_eq = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, "seal")
            self.ee_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"ee_{M.N_EE - 1}")
            self.ee_len = p["ee_len"] / M.N_EE
        mujoco.mj_forward(m, d)

    def _grow(self) -> None:
        for k in ("present", "site_buf", "quat_buf", "force", "tpos_buf", "tquat_buf"):
            if hasattr(self, k):
                a = getattr(self, k)
                setattr(self, k, np.concatenate([a, np.empty_like(a)]))

    def _eq_force(self, eq: int) -> np.ndarray:
        """The translational force (N, arm frame) of an active equality's first three rows."""
        d, mj = self.d, self.mj
        rows = np.flatnonzero((d.efc_type[: d.nefc] == mj.mjtConstraint.mjCNSTR_EQUALITY) & (d.efc_id[: d.nefc] == eq))
        return d.efc_force[rows[:3]] if len(rows) >= 3 else np.zeros(3)

    def step(self, shaft: np.ndarray) -> np.ndarray:
        """One physics step with the servos' unloaded loop response `shaft` (9 ticks); returns the
        present positions of this step."""
        i, m, d = self.i, self.m, self.d
        if i == len(self.present):
            self._grow()
        present = self.present
        self.shaft = shaft
        present[i] = shaft - self.defl
        if i:
            present[i] = np.clip(present[i], present[i - 1] - self.rate_step, present[i - 1] + self.rate_step)
        self.free_len = free_len = -M.K_TICK * present[i]  # cable free length relative to the straight arm
        d.ctrl[:] = free_len
        self.mj.mj_step(m, d)
        self.site_buf[i] = d.site_xpos
        self.quat_buf[i] = d.xquat
        self.force[i] = d.actuator_force
        self.defl = SV.deflection(-self.force[i])
        if self.block is not None:
            self.tpos_buf[i] = d.xpos[self.tb]
            self.tquat_buf[i] = d.xquat[self.tb]
            if self.sealed and self.ev["seal_lost"] is None:
                self.pull.append(np.linalg.norm(self._eq_force(self.seal_eq)))
        self.i += 1
        if i % self.every == 0:
            self._check(i)
        return present[i]

    def _check(self, i: int) -> None:
        m, d, dt, latch, ev = self.m, self.d, self.dt, self.latch, self.ev
        dofs = self.dofs
        # --- fold latch ---
        q = d.qpos
        if not self.latched and ev["latch_on"] is None:
            # the fold forms once S3 has been curled past engage_rad and then starts to open
            # by catch_rad: the folded lattice catches on itself as soon as the curl unloads
            b3 = section_bend(q, dofs, 3)
            if b3 > latch["engage_rad"]:
                self.b3max = max(self.b3max, b3)
            self.b3_hist.append(b3)
            if self.b3max > 0 and b3 < self.b3max - latch["catch_rad"] and ev.get("curl") is None:
                # how fast the curl opens as it catches (over the last RATE_CHECKS checks)
                k = min(RATE_CHECKS, len(self.b3_hist) - 1)
                ev["catch_rate"] = (self.b3_hist[-1 - k] - b3) / (k * self.every * dt) if k else 0.0
                ev["curl"] = sum(section_bend(q, dofs, s) for s in (1, 2, 3))
                if ev["catch_rate"] < latch["catch_rate_rad_s"]:
                    # opened slowly (a ramped slackening): the tip slides along the arm instead of
                    # swinging into it and hooking, so there is no latch and the servos drag the release
                    ev["curl"] = 0.0
                # the curled tip can only hook onto the arm when the whole curl (sum of the
                # section bends) reaches curl_min; beyond curl_max it hooks so deep that the
                # S1 cables no longer clamp the fold and slackening them cannot open it (jam)
            if ev.get("curl") is not None and ev["curl"] >= latch["curl_min"]:
                self.latched = True
                m.eq_data[self.eq_ids, 0] = q[self.eq_qadr]
                d.eq_active[self.eq_ids] = 1
                self.clamp = int(np.argmax(self.shaft[:3]))  # the most wound S1 cable
                ev["latch_on"] = i * dt
        elif self.latched:
            m.eq_data[self.creep_ids, 0] -= m.eq_data[self.creep_ids, 0] * self.relax  # the TPU fold relaxes
            # the fold is clamped shut by the S1 cables: it pops once the most wound one hangs
            # open_m slack (servo paid out more than the held shape needs); a fuse at break_nm
            slack = self.free_len[self.clamp] - d.ten_length[self.clamp]
            load = np.abs(d.qfrc_constraint[self.latch_dofs]).sum()
            jammed = ev["curl"] > latch["curl_max"]
            if (slack > latch["open_m"] and not jammed) or load > latch["break_nm"]:
                self.latched = False
                d.eq_active[self.eq_ids] = 0
                ev["latch_off"] = i * dt
                ev["latch_cause"] = "slack" if slack > latch["open_m"] else "load"
        # --- cup seal on the target face ---
        target, seal = self.target, self.seal
        if target is not None and not self.sealed and i >= 8:
            cup_i = self.site_buf[i, self.cup_site]
            R, normal, half = self.R, self.normal, self.half
            tpos = self.tpos if self.block is None else self.tpos_buf[i]
            if self.block is not None:
                R = quat_to_mat(self.tquat_buf[i])
            rel = R.T @ (cup_i - tpos)  # cup in block coordinates
            gap = float(rel @ normal) - self.face - CUP_R  # < 0: the cup is compressed into the face
            lateral = np.abs(rel) * (1 - np.abs(normal))
            if -2 * self.face < gap < seal["gap_m"] and np.all(lateral <= half + seal["overlap_m"]):
                v = (cup_i - self.site_buf[i - 8, self.cup_site]) / (8 * dt)
                axis = -d.xmat[self.ee_body].reshape(3, 3)[:, 1]  # cup axis: local -Y of the cup body
                n_in = -(R @ normal)  # into the block
                tilt = float(np.degrees(np.arccos(np.clip(axis @ n_in, -1, 1))))
                if ev["contact"] is None:
                    ev.update(contact=i * dt, contact_speed=float(np.linalg.norm(v)), contact_tilt=tilt)
                if float(v @ n_in) >= seal["speed_mps"] and tilt <= seal["tilt_deg"]:
                    self.sealed = True
                    m.eq_data[self.seal_eq, 0:3] = [0.0, -self.ee_len, 0.0]
                    m.eq_data[self.seal_eq, 3:6] = R.T @ (cup_i - tpos)
                    d.eq_active[self.seal_eq] = 1
                    ev.update(sealed=i * dt, seal_speed=float(np.linalg.norm(v)), seal_tilt=tilt)
        # --- the block on its support, on the cup (deployment) ---
        if self.block is not None and self.pull:
            f = float(np.mean(self.pull))
            self.pull = []
            if ev["released"] is None and f > self.block["release_n"]:
                d.eq_active[self.support] = 0  # pulled off its support
                ev["released"] = i * dt
            elif f > self.block["hold_n"]:
                d.eq_active[self.seal_eq] = 0  # the seal lets go; the block falls
                ev["seal_lost"] = i * dt
                ev["seal_lost_n"] = f

    def trial(self, n: int | None = None) -> Trial:
        """The first n steps (all if None) as a Trial."""
        n = self.i if n is None else min(n, self.i)
        s = self.site_buf[:n]
        tr = Trial(np.arange(1, n + 1) * self.dt, s[:, self.sites], self.quat_buf[:n][:, self.bodies],
                   s[:, self.cup_site], -self.force[:n], self.present[:n], s[:, self.mount_site], self.ev)
        if self.block is not None:
            tr.target_pos, tr.target_quat = self.tpos_buf[:n], self.tquat_buf[:n]
        return tr


def run(
    p: dict,
    shaft: np.ndarray,
    dt: float,
    latch: dict,
    scene: Scene = NO_TARGET,
    wrench: dict | None = None,
    rate: np.ndarray | None = None,
) -> Trial:
    """Step the arm with the servos' unloaded loop response `shaft` (T, 9 ticks, one row per
    physics step, servo.present_from_goal). Every step the present position is the shaft minus
    the loop's deflection under the cable tension of the step before (servo.deflection; the loop
    is 50x stiffer than the cable, so the explicit coupling is stable), and the cable's free
    length follows it. The gearbox is not backdrivable: the load moves the loop no faster than
    the motor runs, so the present position changes by at most `rate` (tick/s per servo, default
    the rated ceiling) per step. `wrench`: external forces (N, arm frame) {"mount": (T, 3), "proximal":
    (T, 3)}, applied (MuJoCo xfrc_applied) on the rows where they are non-zero. `scene`: the target,
    if any (Scene)."""
    import mujoco

    n_steps = shaft.shape[0]
    arm = Arm(p, dt, latch, scene=scene, rate=rate, n=n_steps)
    m, d = arm.m, arm.d
    pushed = []
    if wrench is not None:
        for name, key in ((0, "mount"), (M.PROXIMAL, "proximal")):
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "base" if name == 0 else name)
            pushed.append((bid, np.asarray(wrench[key], float)))
        active = np.flatnonzero(np.any([np.any(force != 0, axis=1) for _, force in pushed], axis=0))
        span = (active[0], active[-1] + 1) if len(active) else (n_steps, n_steps)
    for i in range(n_steps):
        if pushed and span[0] <= i <= span[1]:
            for bid, force in pushed:
                d.xfrc_applied[bid, :3] = force[i] if i < span[1] else 0.0
        arm.step(shaft[i])
    return arm.trial()
