"""The fast ensemble path of rollout.py at policy search's longer horizon, and its optional states."""

import numpy as np
import torch

from embodied_snap.dynamics.model import TIP, Dynamics, norm_stats
from embodied_snap.dynamics.rollout import Ensemble
from embodied_snap.resample import COMMAND_COLUMNS, STATE_COLUMNS

from paper_protocol import PROTO

torch.set_num_threads(1)
LOOKAHEAD = PROTO.windows.lookahead


def members(synthetic_frames, n=3):
    f = synthetic_frames(n_groups=3, n=200)
    X, U = f[STATE_COLUMNS].to_numpy(np.float32), f[COMMAND_COLUMNS].to_numpy(np.float32)
    stats = norm_stats(X, U, f.group_id.to_numpy())
    ms = []
    for s in range(n):
        torch.manual_seed(s)
        m = Dynamics(stats, LOOKAHEAD)
        torch.nn.init.normal_(m.head.weight, std=0.02)  # a nonzero residual that stays physical
        ms.append(m.eval())
    return ms, X, U


def test_long_horizon_and_states_equal_each_model(synthetic_frames):
    ms, X, U = members(synthetic_frames)
    ens = Ensemble(models=ms, device="cpu")
    for horizon in (1, 72):  # policy search rolls out ~72 steps; 1 is the loop's edge
        a = 30 + 3 * np.arange(12)
        xs = torch.from_numpy(X[a[:, None] + np.arange(-20, 1)])
        us = torch.from_numpy(U[a[:, None] + np.arange(-19, horizon + 5)])
        out = ens.rollout(xs.reshape(3, 4, 21, 21), us.reshape(3, 4, *us.shape[1:]), horizon, states=True)
        assert out["states"].shape == (3, 3, 4, horizon + 1, 21)
        np.testing.assert_array_equal(out["states"][..., TIP], out["tip"])
        st = out["states"].reshape(3, 12, horizon + 1, 21)
        np.testing.assert_array_equal(st[:, :, 0], np.broadcast_to(xs[:, -1].numpy(), (3, 12, 21)))
        with torch.inference_mode():
            for s, m in enumerate(ms):
                ref = m.rollout(xs, us, horizon).numpy()
                np.testing.assert_allclose(st[s, :, 1:, TIP], ref[..., TIP], atol=2e-5, rtol=0)
                assert (np.abs(st[s, :, 1:] - ref) / m.x_sd.numpy()).max() < 1e-3  # servo ticks too
    assert "states" not in ens.rollout(xs, us, 1)


def test_mean_and_disagreement(synthetic_frames):
    ms, X, U = members(synthetic_frames)
    a = 40 + np.arange(5)
    xs, us = X[a[:, None] + np.arange(-20, 1)], U[a[:, None] + np.arange(-19, 25 + 5)]
    out = Ensemble(models=ms, device="cpu").rollout(xs, us, 25)
    tip = out["tip"]
    np.testing.assert_allclose(out["mean"], tip.mean(0), atol=1e-6)
    dis = np.linalg.norm(tip - tip.mean(0), axis=-1).mean(0)
    np.testing.assert_allclose(out["disagreement"], dis, atol=1e-6)
    assert out["tip"].dtype == np.float32 and out["disagreement"].shape == (5, 26)
