"""Simulator.run end to end on a hand-built case with a closed-form answer (issue 25, item 5).

The ensemble is three one-layer GRUs whose weights are set by hand: a hidden unit saturates at +1
while S1's cable-3 goal is held and at -1 once it is released, and the head turns that into a tip
acceleration of A along x only after the release. Member s also carries a constant tip-z residual
B_s = (+B, 0, -B), which leaves the ensemble mean alone and makes the disagreement known. The hold
bank is one resting arm, keyed by the commands themselves (C_h = 1); P_snap is 1.

Grid (protocol dt = 0.02 s): state frame k lies at anchor + k dt after the S2 release, with the
half-step anchor -dt/2 (the hold's last frame lies half a frame before the S2 release). With
tau = 0.5 s the first frame whose S1 goal is released is k_s1 = 26 (0.51 s; frame 25 is 0.49 s).
The prediction of frame k reads the goal of frame k - 1, so the tip rests through frame 26 and
then x_{26+m} = x_rest + A m (m + 1) / 2. The horizon is H = ceil((0.675 + 0.75 + 0.01) / 0.02) =
72 frames.
"""

import numpy as np
import pytest
import torch

from embodied_snap.dynamics.model import AXIS, TIP, Dynamics
from embodied_snap.dynamics.rollout import Ensemble
from embodied_snap.policy.simulate import SimSettings, Simulator

from paper_protocol import PROTO

torch.set_num_threads(1)
A, B = 1e-3, 1e-5  # m per step^2: the snap's acceleration along x; each member's z drift
WIDTH, GAIN, THRESHOLD = 4, 0.05, 1300.0  # GRU width; switch gain (1/tick) and goal threshold (ticks)
REST = np.array([0.0, -0.5, 0.0])  # tip at rest; the tip axis points down (-y)
EE = 0.15  # end effector: the cup rests at (0, -0.65, 0)
CMD = dict(rho1=3000.0, rho2=2700.0, rho3=2900.0, s3=500.0, dphi=0.0, tau=0.5)
REWARD = dict(d_f_m=0.08, sigma_g_m=0.02, sigma_a_m=0.03, sigma_b_m=0.10, v_min_sim_mps=0.80,
              v_s_mps=0.12, sigma_t_s=0.10, lambda_per_m=1.5)


def _member(z_drift: float) -> Dynamics:
    stats = dict(x_mu=np.zeros(21), x_sd=np.ones(21), v_sd=np.ones(21), u_mu=np.zeros(9), u_sd=np.ones(9),
                 r_sd=np.ones(21))
    m = Dynamics(stats, PROTO.windows.lookahead, width=WIDTH, layers=1)
    H = WIDTH
    with torch.no_grad():
        for p in m.parameters():
            p.zero_()
        m.gru.bias_ih_l0[H:2 * H] = -50.0  # update gate z = 0: h <- n, no memory
        col = 2 * 21 + 2  # the frame's u_k, goal column 2 (S1, cable at 240 deg)
        m.gru.weight_ih_l0[2 * H, col] = GAIN  # n_0 = tanh(GAIN (goal - THRESHOLD)) = +1 held, -1 released
        m.gru.bias_ih_l0[2 * H] = -GAIN * THRESHOLD
        m.head.weight[TIP.start, 0] = -A / 2  # x residual A (1 - n_0) / 2: 0 held, A released
        m.head.bias[TIP.start] = A / 2
        m.head.bias[TIP.start + 2] = z_drift
    return m.eval()


class _Snap:
    def predict(self, rho1, rho2):
        return np.ones(np.shape(rho1))


def _simulator(drifts=(B, 0.0, -B)) -> Simulator:
    x = np.zeros((1, PROTO.windows.history + 1, 21), np.float32)
    x[..., TIP], x[..., AXIS] = REST, [0.0, -1.0, 0.0]
    bank = dict(q=np.array([[CMD[k] for k in ("rho1", "rho2", "rho3")] + [CMD["s3"]]]) / [1500, 1500, 1500, 1000],
                x=x, n=np.array([0.0, -1.0, 0.0]))
    ws = dict(bin_lo_deg=180.0, bin_width_deg=10.0, rho_max=[[4000.0, 4000.0, 4000.0]])
    ens = Ensemble(models=[_member(b) for b in drifts], device="cpu")
    settings = SimSettings(policy=dict(workspace_fraction=1.0, reward=REWARD), after_s1=0.75, ee_m=EE, proto=PROTO)
    return Simulator(ens, bank, _Snap(), ws, settings)


def test_simulator_strike_release_frame_and_penalty_known_answer():
    """Target at the resting cup, face normal +x. Known answer: closest approach at the S1 release
    frame k_s1 = 26 itself (t_ca = 0.52 s, miss, gap and lateral 0; a search from frame 27 finds
    the cup A away, one from 25 finds t_ca 0.50 s); peak speed over the last step 71 -> 72,
    v_pk = 46 A / dt = 2.3 m/s at t_pk = 71.5 dt = 1.43 s; disagreement: members at z = +-B k(k+1)/2
    and 0, mean distance B k(k+1)/3 per frame, averaged over k = 0..72: B 72 * 74 / 9 = 592 B;
    reward G S (1/2 + H/2) - 1.5 * 592 B with G = sig(0.08/0.02), S = sig((2.3 - 0.8)/0.12),
    H = exp(-(0.52 - 1.43)^2 / (2 * 0.1^2))."""
    sim = _simulator()
    assert sim.H == 72
    act = {k: np.array([v]) for k, v in CMD.items()}
    cup_rest = REST + EE * np.array([0.0, -1.0, 0.0])
    out = sim.run(act, cup_rest[None], np.array([[1.0, 0.0, 0.0]]))
    assert out["t_ca_s"][0] == pytest.approx(0.52)
    assert out["miss_m"][0] == pytest.approx(0.0, abs=1e-6)
    assert out["gap_m"][0] == pytest.approx(0.0, abs=1e-6) and out["lateral_m"][0] == pytest.approx(0.0, abs=1e-6)
    assert out["v_pk_mps"][0] == pytest.approx(46 * A / 0.02, rel=1e-4)
    assert out["t_pk_s"][0] == pytest.approx(1.43)
    assert out["c_h"][0] == 1.0 and out["p_snap"][0] == 1.0
    assert out["disagreement_m"][0] == pytest.approx(592 * B, rel=1e-3)
    sig = lambda z: 1 / (1 + np.exp(-z))  # noqa: E731
    G, S, H = sig(0.08 / 0.02), sig((2.3 - 0.8) / 0.12), np.exp(-((0.52 - 1.43) ** 2) / (2 * 0.1 ** 2))
    assert out["reward"][0] == pytest.approx(G * S * (0.5 + 0.5 * H) - 1.5 * 592 * B, rel=1e-4)
