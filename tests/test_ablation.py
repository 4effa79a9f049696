"""The release-rule ablation's pieces on known answers (issue 13): triggers on synthetic
trajectories, the projection and release steps, the offset fit, the family bootstrap, McNemar and
Wilson against statsmodels and hand values, bend angles and the bend point on synthetic arcs."""

import numpy as np
import pytest
from statsmodels.stats.contingency_tables import mcnemar
from statsmodels.stats.proportion import proportion_confint

from embodied_snap.ablation import kinematics as KM
from embodied_snap.ablation import stats as ST
from embodied_snap.ablation import triggers as TR
from embodied_snap.ablation.targets import sample_families

DT, ANCHOR, TIMING = 0.02, -0.01, (0.45, 0.675)
N_AXIS = np.array([0.0, -1.0, 0.0])  # hanging straight down
LENGTHS = (0.324, 0.230, 0.176)


def arm(thetas_deg, lengths=LENGTHS) -> np.ndarray:
    """State (12,) of three constant-curvature sections bending in the x-y plane by thetas (deg),
    base tangent -y: s1, s2, tip ends and the tip axis."""
    pos, phi, out = np.zeros(2), 0.0, []
    for th, L in zip(np.radians(thetas_deg), lengths, strict=True):
        # chord of an arc: length 2 R sin(th/2), direction at phi + th/2
        c = L if th == 0 else 2 * L / th * np.sin(th / 2)
        d = phi + th / 2
        pos = pos + c * np.array([np.sin(d), -np.cos(d)])
        phi += th
        out += [pos[0], pos[1], 0.0]
    return np.array(out + [np.sin(phi), -np.cos(phi), 0.0])


# --- kinematics --------------------------------------------------------------------------------------

@pytest.mark.parametrize("th", [(0, 0, 0), (30, 0, 0), (20, 45, 10), (60, 30, 90), (0, -40, 70)])
def test_bend_angles_of_constant_curvature_arcs(th):
    # exact for piecewise-constant-curvature arms: magnitudes, whatever the bending direction
    assert np.allclose(KM.bend_angles(arm(th)[None], N_AXIS)[0], np.abs(th), atol=1e-6)


def test_bend_point_single_section():
    for k in range(3):
        th = [0, 0, 0]
        th[k] = 50
        mid = (sum(LENGTHS[:k]) + LENGTHS[k] / 2) / sum(LENGTHS)
        assert KM.bend_point(arm(th)[None], N_AXIS)[0] == pytest.approx(mid, abs=0.03)


def test_travelling_bend_moves_distally():
    # a bend wave running from S1 to S3: the bend point moves distally, correlation near 1
    T = 30
    s = np.linspace(0, 1, T)
    th = np.stack([60 * np.exp(-((s - c) / 0.25) ** 2) for c in (0.0, 0.5, 1.0)], 1)
    x = np.stack([arm(t) for t in th])
    bp = KM.bend_point(x, N_AXIS)
    r = KM.travel(np.arange(T) * DT, bp)
    assert r > 0.9 and bp[-1] > bp[0]
    # the same wave backwards moves proximally
    assert KM.travel(np.arange(T) * DT, bp[::-1]) < -0.9
    st = KM.travel_stats([r, -0.5, np.nan, 0.2])
    assert st == dict(n=3, distal_fraction=pytest.approx(2 / 3), mean_correlation=pytest.approx((r - 0.3) / 3))


def test_rates_and_tip_speed_are_backward_differences():
    y = np.array([[[0.0], [1.0], [3.0]]])
    assert np.allclose(KM.rates(y, 0.5)[0, :, 0], [0, 2, 4])
    x = np.zeros((1, 3, 12))
    x[0, :, 6] = [0.0, 0.01, 0.03]
    assert np.allclose(KM.tip_speed(x, DT)[0], [0, 0.5, 1.0])


# --- triggers ----------------------------------------------------------------------------------------

def test_triggers_fire_at_the_right_step():
    t = np.arange(36)
    s1 = np.where(t >= 12, 20.0, 5.0)[None]  # crosses 15 deg/s at step 12
    s2 = np.exp(-((t - 7) / 3.0) ** 2)[None] * 100  # peak rate at step 7
    tip = np.minimum(t * 0.05, 1)[None]  # 0.4 m/s first reached at step 8
    k = TR.event_steps(s1, s2, tip, 35, 15.0, 0.4)
    assert (k["s1_rate"], k["s2_peak"], k["tip_speed"]) == (12, 7, 8)
    # an event that never fires sits at the last admissible step; step 0 (the hold) never counts
    never = TR.event_steps(np.zeros((1, 36)), s2, np.full((1, 36), 9.0), 35, 15.0, 0.4)
    assert never["s1_rate"] == 35 and never["tip_speed"] == 1


def test_projection_and_release_steps():
    assert np.allclose(TR.project([0.3, 0.5, 0.9], TIMING), [0.45, 0.5, 0.675])
    assert list(TR.at_bound([0.3, 0.45, 0.5, 0.675, 0.9], TIMING)) == [True, False, False, False, True]
    steps, rep = TR.admissible_steps(TIMING, ANCHOR, DT)
    assert list(steps) == list(range(23, 36))  # ceil((0.45 + 0.01) / 0.02) .. ceil((0.675 + 0.01) / 0.02)
    assert list(TR.release_step(rep, ANCHOR, DT)) == list(steps)
    assert (rep >= TIMING[0]).all() and (rep <= TIMING[1]).all()
    # the simulator's own release step (policy.simulate.Simulator.run: k_s1)
    tau = np.array([0.45, 0.5, 0.6, 0.675])
    assert list(TR.release_step(tau, ANCHOR, DT)) == list(np.ceil((tau - ANCHOR) / DT).astype(int))


def test_offset_fit_recovers_the_best_offset():
    steps, _ = TR.admissible_steps(TIMING, ANCHOR, DT)
    t_e = np.array([0.1, 0.2, 0.3, 0.35])
    best = 0.2  # every target does best released 0.2 s after its event
    k_best = TR.release_step(TR.project(t_e + best, TIMING), ANCHOR, DT)
    table = -np.abs(steps[None] - k_best[:, None]).astype(float)
    deltas = np.round(np.arange(-0.4, 0.401, DT), 6)
    d, score = TR.fit_offset(t_e, table, steps, deltas, TIMING, ANCHOR, DT)
    assert d == pytest.approx(best) and score.max() == 0
    # a flat table: every offset ties, the smallest |delta| wins
    assert TR.fit_offset(t_e, np.zeros_like(table), steps, deltas, TIMING, ANCHOR, DT)[0] == 0.0
    with pytest.raises(ValueError):
        TR.lookup(table, steps, np.array([5, 23, 23, 23]))


# --- statistics ----------------------------------------------------------------------------------------

def test_wilson_equals_statsmodels_and_hand_value():
    assert ST.wilson(8, 10) == pytest.approx(list(proportion_confint(8, 10, method="wilson")))
    assert ST.wilson(8, 10) == pytest.approx([0.4902, 0.9433], abs=1e-4)  # (8 + z^2/2 +- ...) / (10 + z^2)
    assert ST.wilson(288, 400) == pytest.approx(list(proportion_confint(288, 400, method="wilson")))


def test_mcnemar_on_hand_made_tables():
    # paired outcomes: 5 both, 1 only a, 7 only b, 3 neither -> exact binomial p = 2 P(X <= 1 | 8, 1/2)
    a = np.array([1] * 5 + [1] + [0] * 7 + [0] * 3, bool)
    b = np.array([1] * 5 + [0] + [1] * 7 + [0] * 3, bool)
    assert ST.paired_table(a, b).tolist() == [[5, 1], [7, 3]]
    r = ST.mcnemar_p(a, b)
    assert r["exact"] and r["discordant"] == [1, 7]
    assert r["p"] == pytest.approx(2 * (1 + 8) / 256)
    assert r["p"] == pytest.approx(mcnemar([[5, 1], [7, 3]], exact=True).pvalue)
    # many discordant pairs: chi-square with continuity correction, as statsmodels computes it
    a = np.r_[np.ones(40, bool), np.zeros(10, bool), np.ones(50, bool)]
    b = np.r_[np.zeros(40, bool), np.ones(10, bool), np.ones(50, bool)]
    r = ST.mcnemar_p(a, b)
    assert not r["exact"]
    assert r["p"] == pytest.approx(mcnemar([[50, 40], [10, 0]], exact=False, correction=True).pvalue)
    assert ST.mcnemar_p(a, a)["p"] == 1.0


def test_family_bootstrap_resamples_whole_families():
    # family A: nine starts of 1, family B: one start of 0. Resampling families gives means 1, 0.9
    # or 0 (BB, probability 1/4), so the 95 % interval reaches 0; resampling starts never would.
    v = np.r_[np.ones(9), 0.0]
    fam = np.r_[np.zeros(9, int), 1]
    lo, hi = ST.family_bootstrap(v, fam, seed=1, n_resamples=2000)
    assert lo == 0.0 and hi == 1.0
    # a resample holding A and B averages its ten starts (0.9), not the two family means (0.5):
    # the middle 40 % of resample means is exactly that mixed draw
    assert ST.family_bootstrap(v, fam, seed=1, n_resamples=4000, level=0.4) == pytest.approx([0.9, 0.9])
    # rows in any order, families by any label: the same interval
    p = np.random.default_rng(0).permutation(10)
    assert ST.family_bootstrap(v[p], np.where(fam[p] == 0, "x", "y"), seed=1, n_resamples=2000) == [lo, hi]
    assert ST.family_bootstrap(np.full(6, 0.3), np.arange(6) // 2, seed=1) == pytest.approx([0.3, 0.3])


# --- target families -----------------------------------------------------------------------------------

def test_families_share_a_strike_point():
    ws = {"strike_points_m": [[0.3, -0.5, 0.0], [0.0, -0.6, 0.3], [-0.2, -0.5, -0.2]],
          "strike_dirs": [[1.0, 0, 0], [0, 0, 1.0], [0, 0, -1.0]], "hanging_axis": [0, -1.0, 0]}
    df = sample_families(ws, 10, 4, seed=3, arc_deg=0.0, jitter_m=0.0)
    assert len(df) == 10 and list(df["family"]) == [0] * 4 + [1] * 4 + [2] * 2
    assert df.groupby("family")["strike_point"].nunique().eq(1).all()
    assert df["strike_point"].iloc[::4].nunique() == 3  # without replacement while there are enough
    P = np.asarray(ws["strike_points_m"])[df["strike_point"]]
    assert np.allclose(df[["x", "y", "z"]].to_numpy(), P)  # no jitter, no turn: the strike point itself
