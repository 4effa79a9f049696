"""Dynamics model (issue 5): known answers for Eq. 3-4, the loss, the hold model, the gate, and a tiny
training run. No timing asserts; the whole file runs in well under a minute."""

import dataclasses

import numpy as np
import pytest
import torch

from embodied_snap import bearing as BR
from embodied_snap.dynamics import evaluate, gate, hold
from embodied_snap.dynamics import model as M
from embodied_snap.dynamics import train as T
from embodied_snap.dynamics.model import TIP, Dynamics, f_cv, n_params, norm_stats
from embodied_snap.dynamics.rollout import Ensemble
from embodied_snap.resample import COMMAND_COLUMNS, STATE_COLUMNS
from embodied_snap.windows import make_windows

from paper_protocol import PROTO

torch.set_num_threads(1)
HISTORY, LOOKAHEAD, HORIZON = 20, 5, 25  # the paper's windows (config `windows`)
DT = 0.02  # 50 Hz (config resample.hz)
# a tiny fit: 4 epochs of 256 windows, scored on 128
TINY = T.TrainSettings(epochs=4, windows_per_epoch=256, val_windows=128, batch_size=64, lr=3e-3, patience=10)


@pytest.fixture(scope="module")
def windows(synthetic_frames):
    f = synthetic_frames()
    tr = make_windows(f[f.group_id < "g4"], dataclasses.replace(PROTO.windows, fast_speed_mps=0.0))
    va = make_windows(f[f.group_id >= "g4"], PROTO.windows)
    return tr, va


def test_gru_parameter_count():
    m = Dynamics(norm_stats(np.ones((5, 21), np.float32), np.ones((5, 9), np.float32), np.zeros(5)), LOOKAHEAD)
    H, n_in = 96, 2 * 21 + 6 * 9
    per_layer = lambda i: 3 * H * (i + H) + 2 * 3 * H  # noqa: E731  W_ih, W_hh, two biases
    assert n_params(m.gru) == per_layer(n_in) + per_layer(H) == 111_744
    assert n_params(m) == 111_744 + 21 * H + 21


def test_cv_prior_exact_on_constant_velocity():
    """At initialisation the residual is zero, so Eq. 4 extrapolates linear motion exactly."""
    rng = np.random.default_rng(1)
    stats = norm_stats(rng.normal(size=(50, 21)).astype(np.float32), rng.normal(size=(50, 9)).astype(np.float32),
                       np.zeros(50))
    m = Dynamics(stats, LOOKAHEAD)
    x0, v = torch.randn(4, 1, 21), torch.randn(4, 1, 21) * 0.01
    k = torch.arange(0, 21 + HORIZON, dtype=torch.float32)[None, :, None]
    xs = x0 + v * k  # x_{t-20} .. x_{t+25}
    us = torch.randn(4, 20 + HORIZON + 4, 9)
    pred = m.rollout(xs[:, :21], us, HORIZON)
    torch.testing.assert_close(pred, xs[:, 21:], atol=1e-5, rtol=0)
    torch.testing.assert_close(f_cv(torch.tensor(3.0), torch.tensor(1.0)), torch.tensor(5.0))


def test_loss_weights():
    w = T.step_weights(HORIZON)
    assert len(w) == 25 and float(w.mean()) == pytest.approx(1.0)
    assert float(w[0] / w[3]) == pytest.approx(2.0)  # h^-1/2: h=1 vs h=4
    f = T.window_factors(np.array([True, False, False]), np.array([False, True, False]))
    assert f.tolist() == [5.0, 3.0, 1.0]


def test_hold_model_synthetic_neighbours():
    bq = np.array([[0.0, 0, 0, 0], [0.3, 0, 0, 0], [3.0, 0, 0, 0]])
    bx = np.array([[0.0], [1.0], [10.0]])
    # Exactly on a hold: its weight is 1/0.01 = 100 against 1/0.3; the far one is not among k=2.
    x, c = hold.predict(bq, bx, np.array([[0.0, 0, 0, 0]]), k=2)
    assert x[0, 0] == pytest.approx((100 * 0 + (1 / 0.3) * 1) / (100 + 1 / 0.3))
    assert c[0] == pytest.approx(0.5 + 0.5 * np.exp(-((0.15 / 0.3) ** 2)))
    # Midway: equal weights, mean distance 0.15.
    x, _ = hold.predict(bq, bx, np.array([[0.15, 0, 0, 0]]), k=2)
    assert x[0, 0] == pytest.approx(0.5)
    # The paper's scale: 1500 ticks of rho1 is distance 1.
    assert hold.SCALE.tolist() == [1500, 1500, 1500, 1000]
    assert hold.axis_deg(np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]]))[0] == pytest.approx(90)


def test_hold_bank_and_loso(synthetic_frames):
    f = synthetic_frames(n_groups=6)
    metas = {f"g{g}": dict(session=f"s{g % 3}", labels=dict(t_s2=1.5),
                           program=dict(rho1=2500 + 100 * g, rho2=2500, rho3=2500, s3=0, bearing=210.0))
             for g in range(6)}
    B = hold.bank(f, metas, 210.0, HISTORY)
    assert B["x"].shape == (6, 21, 21)
    i = hold.release_row(np.arange(140) * 0.02, 1.5)
    g0 = f[f.group_id == "g0"]
    X, U = g0[STATE_COLUMNS].to_numpy(), g0[COMMAND_COLUMNS].to_numpy()
    # At the canonical bearing nothing rotates; servo positions are kept as offsets from the goals.
    np.testing.assert_allclose(B["x"][0, -1, :12], X[i, :12], atol=1e-6)
    np.testing.assert_allclose(B["x"][0, -1, 12:], X[i, 12:] - U[i], atol=1e-4)
    # start() puts the servo positions back on the given goals and rotates by dphi about n.
    prm = dict(rho1=[2500.0], rho2=[2500.0], rho3=[2500.0], s3=[0.0], dphi=[0.0])
    x0, c0 = hold.start(B, prm, U[None, i - 20:i + 1])
    assert x0.shape == (1, 21, 21) and 0.5 < c0[0] <= 1.0
    off, _ = hold.predict(B["q"], B["x"], np.array([[2500, 2500, 2500, 0]]) / hold.SCALE)
    np.testing.assert_allclose(x0[0, -1, 12:], U[i] + off[0, -1, 12:], atol=1e-3)
    x1, _ = hold.start(B, dict(prm, dphi=[90.0]), U[None, i - 20:i + 1])
    tip0, tip1 = x0[0, -1, 6:9], x1[0, -1, 6:9]
    assert np.linalg.norm(tip1) == pytest.approx(np.linalg.norm(tip0), rel=1e-5)
    assert (BR.bearing_deg(tip1, B["n"]) - BR.bearing_deg(tip0, B["n"])) % 360 == pytest.approx(90, abs=1e-3)
    r = hold.leave_one_session_out(B, PROTO.rig.arm_length_m)
    assert r["n_holds"] == 6 and r["n_sessions"] == 3


def test_release_row_is_the_last_frame_strictly_before_the_label():
    t = np.arange(100) / 64.0  # binary-exact frame times: a label can sit exactly on a frame
    assert hold.release_row(t, 40 / 64) == 39  # on frame 40: frame 40 is not before it
    assert hold.release_row(t, 40.5 / 64) == 40  # between frames 40 and 41
    assert hold.release_row(t, 99.5 / 64) == 99  # after the last frame
    assert hold.release_row(t, 0.0) == -1  # nothing before it


def test_hold_bank_ends_on_the_frame_before_the_release(synthetic_frames):
    """The expected rows are read off the frame times by hand: 50 Hz frames at k * 0.02 s."""
    f = synthetic_frames(n_groups=3)
    t = f[f.group_id == "g0"]["t"].to_numpy()
    labels = {"g0": float(t[75]), "g1": float(t[60]) + 0.01, "g2": float(t[90]) - 0.001}
    row = {"g0": 74, "g1": 60, "g2": 89}  # the label on frame 75; halfway 60..61; just before 90
    metas = {g: dict(session="s0", labels=dict(t_s2=labels[g]),
                     program=dict(rho1=2500.0, rho2=2500.0, rho3=2500.0, s3=0.0, bearing=210.0)) for g in labels}
    B = hold.bank(f, metas, 210.0, HISTORY)
    assert B["group_ids"].tolist() == ["g0", "g1", "g2"]
    for j, g in enumerate(B["group_ids"]):
        X = f[f.group_id == g][STATE_COLUMNS].to_numpy()
        np.testing.assert_allclose(B["x"][j, -1, :12], X[row[g], :12], atol=1e-6)  # x_t: the release row
        np.testing.assert_allclose(B["x"][j, 0, :12], X[row[g] - HISTORY, :12], atol=1e-6)  # x_{t-20}
    # a label 20 frames in leaves no full history: that group is left out
    metas["g1"]["labels"]["t_s2"] = float(t[20])  # row 19 < 20
    assert hold.bank(f, metas, 210.0, HISTORY)["group_ids"].tolist() == ["g0", "g2"]
    metas["g1"]["labels"]["t_s2"] = float(t[21])  # row 20: exactly the history, from frame 0
    B = hold.bank(f, metas, 210.0, HISTORY)
    assert B["group_ids"].tolist() == ["g0", "g1", "g2"]
    np.testing.assert_allclose(B["x"][1, 0, :12], f[f.group_id == "g1"][STATE_COLUMNS].to_numpy()[0, :12], atol=1e-6)


def test_loso_known_answer():
    """Two sessions whose holds differ only by a 10 mm tip shift and a 90 deg axis turn: each is
    predicted from the other, so every error is exactly that."""
    x = np.zeros((4, 21, 21))
    x[:, :, 6:9] = [0.0, -0.7, 0.0]
    x[:, :, 9:12] = [0.0, -1.0, 0.0]
    x[2:, :, 6] += 0.010
    x[2:, :, 9:12] = [1.0, 0.0, 0.0]
    B = dict(q=np.zeros((4, 4)), x=x, session=np.array(["a", "a", "b", "b"]), n=np.array([0.0, -1.0, 0.0]))
    r = hold.leave_one_session_out(B, PROTO.rig.arm_length_m)
    assert r["tip_mm_median"] == pytest.approx(10.0) and r["axis_deg_median"] == pytest.approx(90.0)
    assert r["tip_pct_arm_median"] == pytest.approx(10.0 / (PROTO.rig.arm_length_m * 1e3) * 100)


def test_speed_travel_known_answer():
    tip = np.zeros((26, 3))
    tip[:, 0] = np.arange(26) * 0.01  # 1 cm per 20 ms step = 0.5 m/s
    v, d = gate.speed_travel(tip, DT)
    assert v == pytest.approx(0.5) and d == pytest.approx(0.25)


def test_persistence_and_eligible(windows):
    tr, _ = windows
    idx = evaluate.eligible(tr, evaluate.eval_horizon(DT))
    assert len(tr["anchors"]) == 4 * (140 - 48) and len(idx) == 4 * (140 - 58)
    e = evaluate.persistence_tip_mm(tr, idx, evaluate.eval_horizon(DT))
    assert e.shape == (len(idx), 35)
    # persistence predicts x_t: its error at h is |tip(t+h) - tip(t)|, read here from the frames
    X = tr["X"]
    a = tr["anchors"][idx[0]]
    np.testing.assert_allclose(e[0, 4], np.linalg.norm(X[a + 5, TIP] - X[a, TIP]) * 1e3, rtol=1e-5)


@pytest.fixture(scope="module")
def trained(windows):
    tr, va = windows
    model, curve = T.train(tr, va, seed=0, settings=TINY, log=lambda r: None)
    return model, curve


def test_tiny_training_reduces_loss(windows, trained):
    tr, va = windows
    model, curve = trained
    W = T.prepare(va)
    idx = np.arange(128)
    T.seed_all(0)
    prior = Dynamics(norm_stats(tr["X"], tr["U"], tr["group"]), LOOKAHEAD)  # zero residual = f_cv alone
    l0, _ = T.evaluate_loss(prior, W, idx, T.step_weights(HORIZON))
    l1, _ = T.evaluate_loss(model, W, idx, T.step_weights(HORIZON))
    assert l1 < 0.5 * l0
    assert [r["epoch"] for r in curve] == [1, 2, 3, 4]


def test_training_is_deterministic(windows, trained, monkeypatch):
    """... also when config dynamics.device is cuda on a machine without a GPU: the same model, on
    CPU, and one log line saying so; the rollouts fall back the same way."""
    tr, va = windows
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    lines = []
    m2, _ = T.train(tr, va, seed=0, settings=dataclasses.replace(TINY, device="cuda"), log=lines.append)
    for a, b in zip(trained[0].state_dict().values(), m2.state_dict().values()):
        torch.testing.assert_close(a, b, atol=0, rtol=0)
    said = [x for x in lines if isinstance(x, str)]
    assert len(said) == 1 and "no GPU is visible: running on cpu" in said[0]
    assert Ensemble(models=[m2], device="cuda").device == "cpu"


@pytest.mark.slow
def test_seeds_side_by_side_are_each_the_seed_trained_alone(windows, trained):
    """config dynamics.seeds_in_one_job: the seeds trained at once, a forked process each, give
    every seed the model and curve train() gives it alone (the curve's clock aside), in seed order."""
    tr, va = windows
    alone = T.train(tr, va, seed=1, settings=TINY, log=lambda r: None)
    rows = []
    fits = T.train_seeds(tr, va, [1, 0], TINY, threads=1, log=lambda s, r: rows.append(s))
    for (m, c), (m0, c0) in zip(fits, [alone, trained]):
        for a, b in zip(m.state_dict().values(), m0.state_dict().values()):
            torch.testing.assert_close(a, b, atol=0, rtol=0)
        assert [{k: v for k, v in r.items() if k != "seconds"} for r in c] == \
               [{k: v for k, v in r.items() if k != "seconds"} for r in c0]
    assert rows == []  # forked: each seed logged in its own process
    # one seed, or a device other than the CPU: in turn, in this process, each row logged with its seed
    (m, _), = T.train_seeds(tr, va, [1], TINY, log=lambda s, r: rows.append(s))
    assert rows == [1] * 4
    for a, b in zip(m.state_dict().values(), alone[0].state_dict().values()):
        torch.testing.assert_close(a, b, atol=0, rtol=0)


def test_carried_state_vs_reencoded_window(windows, trained):
    """Eq. 4 literally re-encodes x_{t+h-19..t+h}; the carried state also remembers older frames.
    Step 1 is identical; afterwards the gap must stay well below the model's own error."""
    _, va = windows
    model, _ = trained
    W = T.prepare(va)
    xs, us, y = T.batch(W, W["anchors"][:64])
    with torch.inference_mode():
        a = model.rollout(xs, us, HORIZON, carry=True)
        b = model.rollout(xs, us, HORIZON, carry=False)
    torch.testing.assert_close(a[:, 0], b[:, 0], atol=1e-5, rtol=1e-5)
    gap = (a[..., M.TIP] - b[..., M.TIP]).norm(dim=-1).mean()
    err = (a[..., M.TIP] - y[..., M.TIP]).norm(dim=-1).mean()
    assert float(gap) < 0.5 * float(err) + 1e-4


def test_ensemble_rollout_shapes_mean_and_disagreement_known_answer(tmp_path, windows):
    """Three members (saved and loaded) that are the prior plus a constant tip residual of +b, 0 and
    -b along x. From the same start, member s's tip differs from the middle one's by b_s k(k+1)/2 at
    step k (the constant-velocity prior integrates a constant residual twice). Known answer: the
    ensemble mean is the middle member, and the disagreement (mean distance of the members to the
    mean) is (b + 0 + b)/3 * k(k+1)/2 = b k(k+1)/3: 0 at k = 0, 2b/3 at k = 1, 200 b at k = 24."""
    tr, va = windows
    b = 1e-4  # m per step^2
    paths = []
    for s, sign in enumerate((1.0, 0.0, -1.0)):
        m = Dynamics(norm_stats(tr["X"], tr["U"], tr["group"]), LOOKAHEAD)  # zero head: f_cv alone
        with torch.no_grad():
            m.head.bias[TIP.start] = sign * b / m.r_sd[TIP.start]  # residual sign * b along tip x
        p = tmp_path / f"seed{s}.pt"
        M.save(m, p)
        paths.append(p)
    ens = Ensemble(paths, device="cpu")
    W = T.prepare(va)
    xs, us, _ = T.batch(W, W["anchors"][:6])
    out = ens.rollout(xs.reshape(2, 3, 21, 21), us.reshape(2, 3, *us.shape[1:]), HORIZON)
    assert out["tip"].shape == (3, 2, 3, 26, 3) and out["disagreement"].shape == (2, 3, 26)
    k = np.arange(HORIZON + 1)
    offset = b * k * (k + 1) / 2
    np.testing.assert_allclose(out["tip"][0, ..., 0] - out["tip"][1, ..., 0], np.broadcast_to(offset, (2, 3, 26)),
                               atol=2e-6)
    np.testing.assert_allclose(out["mean"], out["tip"][1], atol=2e-6)
    np.testing.assert_allclose(out["disagreement"], np.broadcast_to(b * k * (k + 1) / 3, (2, 3, 26)), atol=2e-6)
    assert out["disagreement"][0, 0, 24] == pytest.approx(200 * b, abs=2e-6)


def test_stacked_ensemble_equals_each_model(windows, trained):
    """The stacked, batched-over-seeds rollout of rollout.py is Dynamics.rollout(carry=True)."""
    tr, va = windows
    T.seed_all(1)
    other = Dynamics(norm_stats(tr["X"], tr["U"], tr["group"]), LOOKAHEAD)
    torch.nn.init.normal_(other.head.weight, std=0.1)  # a second, different member
    ens = Ensemble(models=[trained[0], other], device="cpu")
    W = T.prepare(va)
    xs, us, _ = T.batch(W, W["anchors"][:32])
    out = ens.rollout(xs, us, HORIZON)
    with torch.inference_mode():
        for s, m in enumerate(ens.models):
            ref = m.rollout(xs, us, HORIZON)[..., M.TIP].numpy()
            np.testing.assert_allclose(out["tip"][s, :, 1:], ref, atol=2e-5, rtol=0)
