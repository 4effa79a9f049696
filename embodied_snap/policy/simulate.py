"""The hardware-gated simulator that policy search runs on (paper IV-A/IV-B, section V protocol).

For commands (rho1, rho2, rho3, s3, dphi, tau) and canonical targets: the hold model gives the
pre-release configuration at bearing phi0 + dphi (the state history before the S2 release), the
primitive's goal map (embodied_snap.primitive.release_goals, the same map the servos get) gives the nine
goal schedules through the S2 and S1 releases, and the three-seed GRU ensemble rolls the arm out
(Eq. 4) until after_s1 past the latest S1 release. The cup is the tracked tip extended along the
tip axis by the end effector's length. Reward and attachment follow Eq. 9-11. The grid step, the
window history, the canonical bearing, the S2 ramp and the timing set are the protocol's.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from ..characterize import snap as SN
from ..cup import cup_from_axis
from ..dynamics import hold
from ..dynamics.model import AXIS, TIP
from ..dynamics.rollout import Ensemble
from ..primitive import release_goals
from ..protocol import Protocol, from_params, load
from . import reward as RW
from .actions import project_timing, workspace_clamp


@dataclass(frozen=True)
class SimSettings:
    """A simulator's settings, apart from what it loads from the workflow's files."""

    policy: dict  # config policy: its workspace_fraction, reward (Eq. 9-11) and device
    after_s1: float  # how long the rollout runs past the latest S1 release (s), config dynamics.after_s1_s
    ee_m: float  # the end effector's length (m) that extends the tracked tip to the cup, config rig.end_effector_m
    proto: Protocol  # the protocol's sampling, windows and primitive sections

    @classmethod
    def from_config(cls, cfg: dict) -> SimSettings:
        """The settings of a whole config (the benches; a workflow job has its params, `for_job`)."""
        return cls(policy=cfg["policy"], after_s1=cfg["dynamics"]["after_s1_s"], ee_m=cfg["rig"]["end_effector_m"],
                   proto=load(cfg))


class Simulator:
    def __init__(self, ensemble, bank: dict, snap, workspace: dict, settings: SimSettings):
        """ensemble: the GRU ensemble (`Ensemble`); bank: the hold bank; snap: the P_snap model;
        workspace: the measured workspace (workspace.json)."""
        proto, after_s1 = settings.proto, settings.after_s1
        self.ens, self.bank, self.snap, self.ws = ensemble, bank, snap, workspace
        self.cfg, self.ee_m = settings.policy, settings.ee_m
        self.dt, self.history = proto.sampling.dt, proto.windows.history
        self.phi0, self.s2_ramp = proto.primitive.phi0_deg, proto.primitive.s2_ramp_s
        self.timing = proto.primitive.timing_s
        dt = self.dt
        self.anchor_s = -dt / 2  # the hold's last frame lies half a frame before the S2 release starts
        self.H = int(np.ceil((self.timing[1] + after_s1 - self.anchor_s) / dt))
        # goal times relative to the S2 release: u_{t-20} .. u_{t+H+4} around the anchor t
        self.t_u = self.anchor_s + dt * np.arange(-self.history, self.H + ensemble.lookahead)

    def commands(self, act: dict) -> dict:
        """Workspace clamp in the commanded bearing, then Eq. 8."""
        act = workspace_clamp(act, self.phi0 + act["dphi"], self.ws, self.cfg["workspace_fraction"])
        act["tau"] = project_timing(act["tau"], self.timing)
        return act

    def run(self, act: dict, p: np.ndarray, normal: np.ndarray) -> dict:
        """Clamped commands act {name: (N,)} against canonical targets p, normals (N, 3)."""
        act = self.commands(act)
        rho = np.stack([act["rho1"], act["rho2"], act["rho3"]], -1)
        U = release_goals(rho, act["s3"], self.phi0 + act["dphi"], self.t_u, 0.0, act["tau"], self.s2_ramp)
        xs, c_h = hold.start(self.bank, act, U[:, :self.history + 1])
        out = self.ens.rollout(xs, U[:, 1:], self.H, parts=(TIP, AXIS))
        tip, axis = out["mean_parts"]
        cup = cup_from_axis(tip, axis, self.ee_m)
        k_s1 = np.ceil((act["tau"] - self.anchor_s) / self.dt).astype(int)
        s = RW.strike(cup, tip, p, normal, k_s1, self.dt)
        p_snap = self.snap.predict(act["rho1"], act["rho2"])
        dis = out["disagreement"].mean(-1)
        r = RW.reward(s, c_h, p_snap, dis, self.cfg["reward"])
        return dict(act, **s, reward=r, c_h=c_h, p_snap=p_snap, disagreement_m=dis)


def from_files(models, bank_path, snap_path, workspace_path, settings: SimSettings, device=None):
    """The simulator of a workflow job: ensemble, hold bank, P_snap and workspace from their files."""
    with np.load(bank_path) as z:
        bank = {k: z[k] for k in ("q", "x", "n")}
    ws = json.load(open(workspace_path))
    return Simulator(Ensemble(models, device=device), bank, SN.load(snap_path), ws, settings), ws


def for_job(inputs, params):
    """The simulator of a workflow job whose rule takes SIMULATOR inputs and SIMULATOR_PARAMS params
    (rules/policy.smk): the ensemble (on config policy.device), hold bank, P_snap, workspace,
    config policy and protocol."""
    I, P = inputs, params
    settings = SimSettings(policy=P.policy, after_s1=P.after_s1, ee_m=P.ee_m, proto=from_params(P.protocol))
    return from_files(I.models, I.bank, I.snap, I.workspace, settings, device=P.policy["device"])
