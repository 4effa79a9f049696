"""Each characterisation fit on synthetic data with a known answer (fast, no rig, no workflow)."""

import json

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from embodied_snap.characterize import attachment, delay, heldbase, kinematics, release, servo, snap
from embodied_snap.characterize import mocap as M
from embodied_snap.characterize.claims import OURS
from embodied_snap.characterize.claims import rows as claim_rows
from embodied_snap.reference import paper_values

from paper_protocol import PROTO


def quat_axis_angle(axis, ang):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.r_[np.cos(ang / 2), np.sin(ang / 2) * axis]


# --- servo: first-order, rate-limited fit ---------------------------------------------------------

def synthetic_bursts(rate, tau, n=6, seed=0):
    rng = np.random.default_rng(seed)
    grid = np.arange(0.0, 1.6, servo.DT)
    out = []
    for _ in range(n):
        amp = rng.uniform(800, 2500, 3) * np.array([1, -1, -0.5])
        G = np.where((grid >= 0.3) & (grid < 1.2), amp[:, None], 0.0)
        W = servo.simulate(grid, G, np.zeros(3), rate, tau)
        t = np.cumsum(rng.uniform(0.006, 0.014, 150))
        t = t[t < grid[-1]]
        k = np.round(t / servo.DT).astype(int)
        out.append(dict(t=t, goal=np.round(G[:, k].T), present=np.round(W[:, k].T), t_changes=(0.3, 1.2)))
    return out


def test_servo_fit_recovers_rate_and_time_constant():
    fit = servo.fit(synthetic_bursts(2800.0, 0.04))
    assert fit["rate_tick_s"] == pytest.approx(2800.0, rel=0.02)
    assert fit["tau_s"] == pytest.approx(0.04, rel=0.1)


def first_order_rate_limited_step(t, t0, w_from, goal, rate, tau):
    """Closed form of dw/dt = clip((goal - w) / tau, -rate, rate) after a step of the goal at t0:
    a ramp at the full rate until the error has fallen to rate * tau (at t1), then the error decays
    as exp(-(t - t1) / tau). Written out here, independent of servo.simulate."""
    e0 = goal - w_from
    s, ramp = np.sign(e0), max(abs(e0) - rate * tau, 0.0) / rate
    t1 = t0 + ramp
    e1 = e0 - s * rate * ramp  # the error left when the ramp ends (+-rate*tau, or e0 if no ramp)
    return np.where(t < t0, w_from,
                    np.where(t < t1, w_from + s * rate * (t - t0), goal - e1 * np.exp(-(t - t1) / tau)))


def closed_form_bursts(rate, tau, n=6, seed=1):
    """Bursts like the calibration's: goal 0 -> A at 0.3 s, back to 0 at 1.2 s, logged at jittered
    ~100 Hz and rounded to ticks. Amplitudes from 100 ticks (no ramp at all: tau alone) to 1500."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        t = np.cumsum(rng.uniform(0.006, 0.014, 150))
        t = t[t < 1.599]
        amp = np.array([100.0 + 280 * i, -(1500.0 - 200 * i), 0.5 * (100.0 + 280 * i)])
        goal, present = np.zeros((len(t), 3)), np.zeros((len(t), 3))
        for j, a in enumerate(amp):
            up = first_order_rate_limited_step(t, 0.3, 0.0, a, rate, tau)
            at_12 = float(first_order_rate_limited_step(np.array([1.2]), 0.3, 0.0, a, rate, tau)[0])
            down = first_order_rate_limited_step(t, 1.2, at_12, 0.0, rate, tau)
            present[:, j] = np.where(t < 1.2, up, down)
            goal[:, j] = np.where((t >= 0.3) & (t < 1.2), a, 0.0)
        # the log shows a goal change at its first sample after it; t_changes are the labelled times
        out.append(dict(t=t, goal=np.round(goal), present=np.round(present), t_changes=(0.3, 1.2)))
    return out


def test_closed_form_step_is_what_it_says():
    t = np.array([0.0, 0.3, 0.3 + (1000 - 2000 * 0.05) / 2000, 1.0])
    w = first_order_rate_limited_step(t, 0.3, 0.0, 1000.0, 2000.0, 0.05)
    assert w[0] == 0.0 and w[1] == 0.0 and w[2] == pytest.approx(900.0)  # ramp ends 100 ticks short
    assert w[3] == pytest.approx(1000.0 - 100.0 * np.exp(-(1.0 - 0.75) / 0.05))
    w = first_order_rate_limited_step(np.array([0.35]), 0.3, 0.0, 50.0, 2000.0, 0.05)  # 50 < rate*tau
    assert w[0] == pytest.approx(50.0 * (1 - np.exp(-1.0)))


@pytest.mark.parametrize("rate, tau", [(2800.0, 0.04), (1800.0, 0.08)])
def test_servo_fit_recovers_a_closed_form_servo(rate, tau):
    """The fit against bursts it did not make: the exact continuous response. Its Euler step
    (servo.DT = 1 ms against tau >= 40 ms) costs at most a few % of tau."""
    fit = servo.fit(closed_form_bursts(rate, tau))
    assert fit["rate_tick_s"] == pytest.approx(rate, rel=0.02)
    assert fit["tau_s"] == pytest.approx(tau, rel=0.05)
    assert fit["rmse_ticks"] < 3.0 and fit["n_series"] == 18


def test_servo_simulate_matches_the_closed_form():
    grid = np.arange(0.0, 1.0, servo.DT)
    G = np.where(grid >= 0.2, 1200.0, 0.0)[None]
    w = servo.simulate(grid, G, np.zeros(1), 2500.0, 0.05)[0]
    # the model sees the goal one step late (explicit Euler on goal[k-1])
    ref = first_order_rate_limited_step(grid, 0.2 + servo.DT, 0.0, 1200.0, 2500.0, 0.05)
    assert np.max(np.abs(w - ref)) < 0.02 * 1200


def test_eq2_ceilings():
    assert servo.ceilings(3000.0, [3000.0, 1500.0, 1000.0]) == pytest.approx([1.0, 2.0, 3.0])


# --- kinematics: Eq. 1 on the taut envelope -------------------------------------------------------

def test_lever_ratios_from_taut_envelope_with_slack_and_stretch():
    rng = np.random.default_rng(1)
    lever, stretch = np.array([2000.0, 1500.0, 1200.0]), 4.0
    rows = []
    for _ in range(900):
        s = rng.integers(1, 4)
        f = np.where(np.arange(3) < s, rng.uniform(-0.8, 0.8, 3), 0.0)
        geo = f @ lever
        if rng.random() < 0.6:  # taut: on Eq. 1 plus the stretch its load explains
            cur = 15 + rng.uniform(0, 40)
            w = geo + stretch * (cur - 15) + rng.normal(0, 3)
        else:  # slack: paid out more than the path needs, no load
            cur = 15 + rng.normal(0, 1)
            w = geo - rng.uniform(20, 600)
        rows.append(dict(f1=f[0], f2=f[1], f3=f[2], w=w, current=cur))
    rows += [dict(window="rest", f1=0.0, f2=0.0, f3=0.0, w=0.0, current=15 + rng.normal(0, 1)) for _ in range(50)]
    fit = kinematics.fit_levers(rows, quantile=0.9)
    assert fit["lever_ticks_per_rad"] == pytest.approx(lever, rel=0.03)
    assert fit["stretch_ticks_per_ma"] == pytest.approx(stretch, rel=0.1)


def test_travel_per_tick_known():
    # 1 rad of S1 bend over a 40 mm guide offset, 2000 ticks: 20 um/tick
    rows = [dict(window="hold", commanded=True, current=40.0, f1=1.0, f2=0.0, f3=0.0, w=2000.0 + 2.0 * 25)]
    lever = dict(intercept_ticks=0.0, stretch_ticks_per_ma=2.0, idle_ma=15.0)
    out = kinematics.travel_per_tick_um(rows, lever, [0.04, 0.02, 0.02])
    assert out["median"] == pytest.approx(20.0)


# --- mocap kinematics -----------------------------------------------------------------------------

def test_bend_angle_and_direction():
    # bending toward +X tilts the -Y tangent toward +X: a rotation about +Z by +theta
    theta = 0.7
    for phi in (0.0, 1.0, 2.5, -2.0):
        axis = np.cross([0, -1, 0], [np.cos(phi), 0, np.sin(phi)])
        q = quat_axis_angle(axis, theta)
        th, ph = M.bend(np.array([1.0, 0, 0, 0]), q)
        assert th == pytest.approx(theta, abs=1e-9)
        assert ph == pytest.approx(phi, abs=1e-9)


def test_tip_speed_and_bend_rate_of_known_motion():
    t = np.arange(0, 1, 1 / 240)
    n = len(t)
    mc = pd.DataFrame({"t": t})
    for b in ("base", "s1", "s2", "tip"):
        for f in "xyz":
            mc[f"{b}_{f}"] = 0.0
        mc[f"{b}_qw"], mc[f"{b}_qx"], mc[f"{b}_qy"], mc[f"{b}_qz"] = 1.0, 0.0, 0.0, 0.0
        mc[f"{b}_valid"] = True
    mc["tip_x"] = 1.5 * t  # 1.5 m/s
    q = np.array([quat_axis_angle([0, 0, 1], 2.0 * ti) for ti in t])  # S3 bends at 2 rad/s
    mc[["tip_qw", "tip_qx", "tip_qy", "tip_qz"]] = q
    assert np.nanmedian(M.tip_speed(mc, PROTO.sampling.max_gap_s)) == pytest.approx(1.5, rel=1e-6)
    r = M.section_rates(mc, PROTO.sampling.max_gap_s)
    assert np.nanmedian(r[:, 2]) == pytest.approx(2.0, rel=1e-3)
    assert np.nanmax(r[:, :2]) == pytest.approx(0.0, abs=1e-9)
    assert n == len(r)


# --- release modes --------------------------------------------------------------------------------

def test_release_summary():
    rows = [dict(category="direct", v_peak=v, rate_peak=[0, 0, 0]) for v in (0.7, 0.72, 0.75)]
    rows += [dict(category="ramped", v_peak=v, rate_peak=[0, 0, 0]) for v in (0.8, 1.4)]
    rows += [dict(category="instantaneous", v_peak=v, rate_peak=[2.0, 4.0, 6.0]) for v in (0.9, 1.5, 1.6, 1.7)]
    for i, r in enumerate(rows):
        r["group_id"] = f"rel_{i:04d}"
    out = release.summarize(rows, [1.0, 2.0, 3.0], 1.0)
    assert out["direct_range_mps"] == [0.7, 0.75]
    assert out["instant_fraction_over_1mps"] == 0.75
    assert (out["ramped_fast_n"], out["ramped_slow_n"]) == (1, 1)  # split at the 1 m/s threshold
    assert out["operating_rate_over_ceiling"] == pytest.approx([2.0, 2.0, 2.0])
    assert out["operating_section_rate_dps"][0] == pytest.approx(np.degrees(2.0))
    lo, hi = out["instant_fraction_ci95"]
    assert lo < 0.75 < hi


# --- attachment -----------------------------------------------------------------------------------

def test_attachment_model_separable_and_counts():
    rng = np.random.default_rng(2)
    rows = []
    for i in range(120):
        v, tilt = rng.uniform(0.6, 1.8), rng.uniform(0, 90)
        rows.append(dict(group_id=f"att_{i:04d}", v_peak=v, tilt_deg=tilt, lateral_m=rng.uniform(0, 0.3),
                         session=f"s{i % 6}", attached=bool(v > 1.0 and tilt < 60)))
    out = attachment.fit(rows, 1.0)
    assert out["auc_grouped_cv"] > 0.9
    assert out["attached_below_1mps"] == 0
    near = [r for r in rows if r["lateral_m"] <= 0.15 and r["v_peak"] > 1.0]
    assert out["near_fast_n"] == len(near)
    assert out["near_fast_fraction"] == pytest.approx(np.mean([r["attached"] for r in near]))
    # the model's probability rises with speed and falls with tilt
    assert attachment.probability(out, 1.6, 10) > attachment.probability(out, 0.8, 10)
    assert attachment.probability(out, 1.6, 10) > attachment.probability(out, 1.6, 85)


def test_grouped_auc_single_class_is_nan():
    X = np.zeros((6, 2))
    assert np.isnan(attachment.grouped_auc(X, np.ones(6, int), np.arange(6)))


# --- snap classifier ------------------------------------------------------------------------------

def test_snap_classifier_known_region(tmp_path):
    rng = np.random.default_rng(3)
    rows = []
    for i in range(300):
        r1, r2 = rng.uniform(2400, 3700), rng.uniform(2100, 3300)
        rows.append(dict(group_id=f"dyn_{i:04d}", rho1=r1, rho2=r2, session=f"s{i % 6}",
                         v_peak=1.5 if r1 + r2 > 5800 else 0.7))
    out = snap.fit(rows, 1.0, grid_n=61)
    assert out["auc_grouped_cv"] > 0.95
    # true area with r1 + r2 > 5800 over the box (geometry), the P > 0.8 part sits inside it
    g1, g2 = np.meshgrid(np.linspace(*out["box"][0], 61), np.linspace(*out["box"][1], 61))
    true_frac = float(np.mean(g1 + g2 > 5800))
    assert 0.6 * true_frac < out["fraction_box_p_gt_0p8"] <= true_frac + 0.05
    assert sum(out["operating_point"]) > 5800
    p = tmp_path / "snap.json"
    p.write_text(json.dumps(out))
    m = snap.load(p)
    assert m.predict(3600, 3200) > 0.9 and m.predict(2450, 2150) < 0.1
    assert m.predict(np.array([3600, 2450]), np.array([3200, 2150])).shape == (2,)


def test_snap_single_class_is_flagged():
    rows = [dict(group_id=f"dyn_{i:04d}", rho1=3000.0 + i, rho2=2700.0 + i, session="s1", v_peak=1.5) for i in range(5)]
    out = snap.fit(rows, 1.0, grid_n=11)
    assert out["degenerate"] and np.isnan(out["auc_grouped_cv"])
    assert out["fraction_box_p_gt_0p8"] == 1.0


# --- delay sweep ----------------------------------------------------------------------------------

def test_delay_sweep_summary():
    speed = {0.15: 1.1, 0.30: 1.2, 0.45: 1.45, 0.50: 1.57, 0.55: 1.6, 0.60: 1.59, 0.65: 1.5, 0.70: 1.4}
    rows = []
    for tau, v in speed.items():
        for k in range(3):
            att = tau >= 0.45 and tau <= 0.65
            rows.append(dict(group_id=f"dly_{len(rows):04d}", tau=tau, v_peak=v + 0.001 * k,
                             closest_m=0.01 if att else 0.1, attached=att))
    out = delay.summarize(rows)
    assert out["best_tau_s"] == 0.55
    assert out["speed_optimal_taus"] == [0.5, 0.6]  # within 3 % of 1.6
    assert out["supported_tau_s"] == [0.45, 0.65]
    assert out["attach_le_030"]["attached"] == 0 and out["attach_le_030"]["n"] == 6
    assert out["attach_ge_045"]["n"] == 18 and out["attach_ge_045"]["attached"] == 15
    assert out["closest_attached_median_m"] == 0.01  # Fig. 3c: the attached trials only


def _sweep(attached_taus, speed=None):
    """Three trials per delay 0.15..0.70 s; the speed peaks at 0.55 s unless `speed` says otherwise."""
    taus = [0.15, 0.30, 0.45, 0.50, 0.55, 0.60, 0.65, 0.70]
    speed = speed or {0.15: 1.1, 0.30: 1.2, 0.45: 1.45, 0.50: 1.5, 0.55: 1.6, 0.60: 1.5, 0.65: 1.45, 0.70: 1.4}
    rows = [dict(tau=t, v_peak=speed[t], closest_m=0.01, attached=t in attached_taus) for t in taus for _ in range(3)]
    return [dict(r, group_id=f"dly_{k:04d}") for k, r in enumerate(rows)]


@pytest.mark.parametrize("attached, supported", [
    ((0.45, 0.50, 0.55, 0.60, 0.65, 0.70), [0.45, 0.70]),  # the run reaches the top tested delay
    ((0.15, 0.30, 0.45, 0.50, 0.55), [0.15, 0.55]),  # ... and the bottom one
    ((0.15, 0.30, 0.45, 0.50, 0.55, 0.60, 0.65, 0.70), [0.15, 0.70]),  # every delay attached
    ((0.45, 0.50, 0.55, 0.65, 0.70), [0.45, 0.55]),  # 0.60 failed: contiguous, no jump over it
    ((0.30, 0.50, 0.55, 0.60), [0.50, 0.60]),
    ((0.55,), [0.55, 0.55]),
])
def test_delay_supported_interval_ends(attached, supported):
    assert delay.summarize(_sweep(attached))["supported_tau_s"] == supported


def test_delay_supported_interval_is_nan_when_the_optimum_did_not_always_attach():
    rows = _sweep((0.45, 0.50, 0.60))
    rows[12]["attached"] = True  # one of three trials at the optimum, 0.55 s
    assert rows[12]["tau"] == 0.55
    out = delay.summarize(rows)
    assert np.isnan(out["supported_tau_s"]).all() and out["per_tau"][4]["attached"] == 1


def test_delay_optimum_at_the_top_end():
    speed = {0.15: 1.1, 0.30: 1.2, 0.45: 1.3, 0.50: 1.4, 0.55: 1.5, 0.60: 1.55, 0.65: 1.58, 0.70: 1.6}
    out = delay.summarize(_sweep((0.60, 0.65, 0.70), speed))
    assert out["best_tau_s"] == 0.70 and out["supported_tau_s"] == [0.60, 0.70]
    assert out["speed_optimal_taus"] == [0.65, 0.70]  # within 3 % of 1.6 is >= 1.552: not 1.55


# --- held-base detectors --------------------------------------------------------------------------

def test_base_detector_fires_after_the_event_causally():
    t = np.arange(0, 3, 1 / 240)
    x = np.zeros((len(t), 3))
    ev = 1.5
    x[:, 0] = np.clip((t - ev) / 0.3, 0, 1) * 10.0  # 10 mm over 0.3 s
    tf = heldbase.fire_time(t, x, 2.0)
    assert ev < tf < ev + 0.1
    # causal: the same signal cut right after the firing time gives the same answer
    k = np.searchsorted(t, tf) + 2
    assert heldbase.fire_time(t[:k], x[:k], 2.0) == tf


def test_heldbase_rates_and_best_clock():
    trials = [dict(event=1.0 + 0.02 * i, t0=0.25, base=1.05 + 0.02 * i, neighbour=np.nan, residual=0.3)
              for i in range(10)]
    trials += [dict(event=3.0, t0=0.25, base=3.5, neighbour=np.nan, residual=0.3)]
    trials += [dict(event=np.nan, t0=0.25, base=3.5, neighbour=np.nan, residual=0.3)]  # no event: not counted
    out = heldbase.rates(trials, 0.1)
    assert out["n"] == 11
    assert out["fraction_within"]["base"] == pytest.approx(10 / 11)
    assert out["fraction_within"]["residual"] == 0.0
    assert out["fraction_within"]["clock"] == pytest.approx(10 / 11)  # one delay covers 1.00-1.18 s


def test_heldbase_detectors_wait_for_their_arming_and_the_snap_is_the_first_fast_tip():
    """Known answers: a 10 mm step at 0.5 s and another at 1.5 s; armed at 1.0 s, the detector fires
    on the second. The snap is the first sample after t_s2 at the attachment speed."""
    t = np.arange(0, 3, 1 / 240)
    x = np.zeros((len(t), 3))
    x[:, 0] = 10.0 * (t >= 0.5) + 10.0 * (t >= 1.5)
    assert 0.48 <= heldbase.fire_time(t, x, 2.0) < 0.6  # (smooth3 spreads a step by a sample)
    assert 1.48 <= heldbase.fire_time(t, x, 2.0, t_arm=1.0) < 1.6
    v = np.where((t > 0.2) & (t < 0.3), 2.0, 0.0) + np.where(t >= 1.7, 1.2, 0.0)
    assert heldbase.snap_time(t, v, 1.0, 1.0) == pytest.approx(t[t >= 1.7][0])
    assert np.isnan(heldbase.snap_time(t, v, 1.0, 1.5))


def test_servo_residual_zero_for_model_servo():
    grid = np.arange(0, 1.0, servo.DT)
    G = np.where(grid >= 0.3, 1500.0, 0.0)[None]
    W = servo.simulate(grid, G, np.zeros(1), 3000.0, 0.03)[0]
    t = np.arange(0.0, 0.99, 0.01)
    k = np.round(t / servo.DT).astype(int)
    sv = pd.DataFrame({"t": t, "goal_1": G[0, k], "present_1": W[k]})
    _, res = heldbase.servo_residual(sv, 3000.0, 0.03, servos=(1,))
    assert np.max(res) < 20.0  # the step lands between log samples: at most a few ms of rate


def _model_log(timing, rng):
    """A model servo (rate 3000, tau 0.03) logged at jittered ~100 Hz reads, its goal stepping at
    row times (timing "row": written in the row's cycle, as a live bus logs) or between rows
    ("interval": sampled from a 1 kHz goal, as the simulated rig logs)."""
    t = np.cumsum(rng.uniform(0.008, 0.012, 150))
    goals = np.where((np.arange(len(t)) // 15) % 2 == 1, 400.0, 0.0)  # a step every 15 rows
    grid = np.arange(0.0, t[-1] + servo.DT, servo.DT)
    k = np.round(t / servo.DT).astype(int)
    ch = np.flatnonzero(np.diff(goals)) + 1  # the rows that show a new goal
    # "row": it acts from that row's time; "interval": half-way through the interval before it
    tc = t[ch] if timing == "row" else 0.5 * (t[ch - 1] + t[ch])
    G = np.full(len(grid), goals[0])
    for c, g in zip(tc, goals[ch]):
        G[grid >= c] = g
    W = servo.simulate(grid, G[None], np.zeros(1), 3000.0, 0.03)[0]
    return pd.DataFrame({"t": t, "goal_1": goals, "present_1": W[k]})


@pytest.mark.parametrize("timing", ["row", "interval"])
def test_servo_residual_reads_the_logs_goal_timing(timing):
    """Read with its own goal timing, a model servo's log leaves under 3 ticks of residual; read
    with the other, a goal acts half a log interval early or late: tens of ticks at a step."""
    sv = _model_log(timing, np.random.default_rng(3))
    other = {"row": "interval", "interval": "row"}[timing]
    _, own = heldbase.servo_residual(sv, 3000.0, 0.03, servos=(1,), timing=timing)
    _, wrong = heldbase.servo_residual(sv, 3000.0, 0.03, servos=(1,), timing=other)
    assert np.max(own) < 3.0
    assert np.max(wrong) > 10.0


def test_peak_rate_reads_a_ramp_through_timestamp_jitter():
    """A servo at its rate ceiling (2900 tick/s) read every 10 ms, each read stamped up to 1 ms
    off (20 draws): the 50 ms least-squares slope reads within 5 % of the rate, its median excess
    under half that of one 20 ms difference (the estimator it replaced, which reads the jitter)."""
    t_true = np.arange(0.0, 0.6, 0.01)
    w = np.clip(2900.0 * (t_true - 0.1), 0.0, 2900.0 * 0.4)[:, None] * np.ones(3)
    (exact,) = servo.peak_rates([dict(t=t_true, present=w)])
    assert exact == pytest.approx(2900.0, rel=1e-9)  # exact stamps: the slope itself
    peak, two = [], []
    for seed in range(20):
        t = t_true + np.random.default_rng(seed).uniform(-0.001, 0.001, len(t_true))
        peak += list(servo.peak_rates([dict(t=t, present=np.round(w))]))
        two.append((np.abs(w[2:] - w[:-2]) / (t[2:] - t[:-2])[:, None]).max())
    assert np.max(np.abs(np.array(peak) / 2900.0 - 1.0)) < 0.05
    assert np.median(peak) - 2900.0 < 0.5 * (np.median(two) - 2900.0)


# --- claims ---------------------------------------------------------------------------------------

def test_every_reference_claim_has_a_value_and_paper_values_come_from_the_reference():
    ref = paper_values()["characterize"]
    assert set(ref) == set(OURS)
    fits = {
        "kinematics": dict(lever_ticks_per_rad=[1.0, 2.0, 3.0], travel_per_tick_um=dict(median=15.0, iqr=[14.0, 16.0])),
        "servo": dict(peak_rate_over_rated_5_95=[0.99, 1.0], rate_tick_s=3000.0, tau_s=0.03, n_bursts=5,
                      rated_tick_s=3140.0, ceiling_rad_s=[1.0, 2.0, 3.0]),
        "release": dict(direct_range_mps=[0.7, 0.8], instant_fraction_over_1mps=1.0, instant_n=3,
                        operating_tip_speed_iqr_mps=[1.5, 1.6], operating_section_rate_dps=[1.0, 2.0, 3.0],
                        operating_rate_over_ceiling=[1.0, 2.0, 3.0], ramped_fast_n=2, ramped_slow_n=1),
        "attachment": dict(attached_below_1mps=0, n=5, near_fast_fraction=0.9, near_fast_n=4, auc_grouped_cv=0.7),
        "snap": dict(auc_grouped_cv=float("nan"), fraction_box_p_gt_0p8=0.3),
        "delay_sweep": dict(speed_optimal_taus=[0.5, 0.6], attach_le_030=dict(fraction=0.0),
                            attach_ge_045=dict(fraction=1.0), n=9, supported_tau_s=[0.45, 0.7],
                            closest_attached_median_m=0.012),
        "heldbase": dict(fraction_within=dict(base=0.7, clock=0.5, residual=0.6, neighbour=0.6),
                         residual_trigger_ticks=12.0, residual_quiet_ticks=3.0, n=4),
    }
    out = {r["claim_id"]: r for r in claim_rows(fits)}
    assert out["lever_ratio_s1"]["paper"] == str(ref["lever_ratio_s1"]["paper"])
    assert out["snap_auc"]["ours"] == ""  # NaN stays visible as missing, never a number
    assert out["direct_release_range_mps"]["ours"] == "[0.7, 0.8]"
    assert out["delay_closest_attached_mm"]["ours"] == "12" and out["ramped_slow_n"]["ours"] == "1"


@settings(max_examples=300, deadline=None, database=None)
@given(n=st.integers(1, 40), k=st.integers(1, 4), limit=st.integers(0, 45), seed=st.integers(0, 2**32 - 1),
       p_nan=st.floats(0.0, 1.0))
def test_bridge_is_pandas_inside_interpolation_bit_for_bit(n, k, limit, seed, p_nan):
    """mocap.bridge replaced DataFrame.interpolate(limit=limit, limit_area="inside") in track(): the
    same samples filled with the same values, to the bit, for any pattern of gaps and any limit."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, k))
    x[rng.random((n, k)) < p_nan] = np.nan
    want = pd.DataFrame(x).interpolate(limit=limit, limit_area="inside").to_numpy() if limit >= 1 else x
    got = M.bridge(x.copy(), limit)
    assert np.array_equal(got, want, equal_nan=True)
