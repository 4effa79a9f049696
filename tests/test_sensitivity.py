"""The starting points, the slope probe and the landscape analysis (docs/policy.md, "Starting point",
"Landscape"): each against a known answer."""

import numpy as np
import pytest
import yaml
from test_policy import RANGES, _workspace

from embodied_snap.policy import landscape, networks, search, sensitivity, targets
from embodied_snap.policy.actions import decode
from embodied_snap.policy.architectures import NAMES


def test_zero_start_is_all_zero_and_glorot_start_has_each_layers_scale():
    assert not networks.initial("shared", {"init": "zero", "sigma0": 0.1}, 3).any()
    start = {"init": "glorot", "sigma0": 0.1, "init_seed": 111}
    th = networks.initial("centralised16", start, 0)
    nets = networks._unpack(th, "centralised16")
    for W, b in nets[0]:
        a = np.sqrt(6 / sum(W.shape))
        assert not b.any()
        assert np.abs(W).max() <= a and np.abs(W).max() > 0.8 * a  # uniform on +-a: its extremes near a
        assert np.std(W) == pytest.approx(a / np.sqrt(3), rel=0.35)
    assert np.array_equal(th, networks.initial("centralised16", start, 0))  # seeded
    assert not np.array_equal(th, networks.initial("centralised16", start, 1))  # each run its own


def test_a_search_starts_where_its_start_says():
    """CMA-ES's initial mean and step are the start's (read back from the run's pickled state)."""
    import pickle

    ws = _workspace()
    tr = targets.sample(ws, 2 * 8, 11, 180, 0.03)
    train, sel = search.Targets(tr, ws), search.Targets(targets.sample(ws, 16, 22, 180, 0.03), ws)
    from test_policy import ToySim

    start = {"init": "glorot", "sigma0": 0.3, "init_seed": 5}
    tgt = search.SearchTargets(train=train, gen_of=np.arange(len(tr)) // 8, select=sel,
                               norm=search.feature_stats(train))
    spec = search.SearchSpec(ranges=RANGES, generations=2, popsize=4, start=start)
    run = search.cmaes(ToySim(), "shared", 2, tgt, spec, progress=False)
    es = pickle.loads(run["state"])
    assert np.array_equal(es.x0, networks.initial("shared", start, 2))
    assert es.sigma0 == 0.3


def test_shared_sections_without_a_section_code_have_one_slope():
    """Known answers: with zero section-code weights the shared network is the same function for every
    section, so the three preload slopes are equal (cosine 1); a centralised network whose rho1, rho2,
    rho3 read d, e, r alone through their own hidden units has orthogonal slopes (cosine 0)."""
    rng = np.random.default_rng(0)
    g = rng.normal(size=(50, 3))
    th = rng.normal(scale=0.5, size=155)
    (W1, _), _, _ = networks._unpack(th, "shared")[0]
    W1[:, 3:] = 0  # views into th
    p = sensitivity.probe("shared", th, g)
    assert all(c == pytest.approx(1.0, abs=1e-9) for c in p["cosine"].values())
    assert p["weight_norm"] == pytest.approx(np.linalg.norm(th))

    th = np.zeros(158)
    (W1, _), (W2, _), (W3, _) = networks._unpack(th, "centralised")[0]
    W1[:3, :3] = 0.5 * np.eye(3)
    W2[:3, :3] = np.eye(3)
    for unit, out in enumerate(sensitivity.PRELOADS):
        W3[out, unit] = 1.0
    p = sensitivity.probe("centralised", th, g)
    assert all(c == pytest.approx(0.0, abs=1e-9) for c in p["cosine"].values())
    assert sensitivity.probe("shared", np.zeros(155), g)["cosine_mean"] is None  # no slope, no angle


def test_reading_is_the_documented_rule():
    def s(shared, central, p):
        return dict(reward={"shared": {"mean": shared}, "centralised": {"mean": central}},
                    reward_tests={"centralised": {"p": p}})

    assert sensitivity.reproduced(s(0.5, 0.4, 0.008)) is True
    assert sensitivity.reproduced(s(0.5, 0.4, 0.05)) is False  # p must be below 0.05
    assert sensitivity.reproduced(s(0.4, 0.5, 0.008)) is False  # significant, the other way
    assert sensitivity.reproduced(dict(reward={"shared": {"mean": 1}}, reward_tests={})) is None


def test_config_names_only_architectures_and_derives_the_benchmark_start():
    cfg = yaml.safe_load(open("config.yaml"))
    schema = yaml.safe_load(open("schemas/config.schema.yaml"))
    enum = schema["properties"]["policy"]["properties"]["sensitivity"]["additionalProperties"]["allOf"][1][
        "properties"]["archs"]["items"]["enum"]
    assert tuple(enum) == NAMES
    assert set(schema["definitions"]["start"]["properties"]["init"]["enum"]) == set(networks.INITS)
    for s in cfg["policy"]["sensitivity"].values():
        networks.initial("shared", s, 0)  # every configured start can be drawn


def test_effective_u_inverts_eq7():
    u = np.random.default_rng(1).uniform(-1, 1, (20, 6))
    assert np.allclose(landscape.effective_u(decode(u, RANGES), RANGES), u)
    act = decode(u, RANGES)
    act["rho1"] = np.minimum(act["rho1"], 2500)  # a clamped preload reads at its clamp
    back = decode(landscape.effective_u(act, RANGES), RANGES)
    assert np.allclose(back["rho1"], act["rho1"])


def test_section_slopes_tell_common_from_distinct():
    rng = np.random.default_rng(2)
    g = rng.normal(size=(100, 3))
    z = landscape.standardise(g)
    u = np.zeros((100, 6))
    j = [networks.ACTIONS.index(f"rho{i}") for i in (1, 2, 3)]
    for k in j:  # one slope for all three, own intercepts
        u[:, k] = 0.1 * k + 0.3 * z[:, 0] - 0.2 * z[:, 2] + rng.normal(0, 0.01, 100)
    same = landscape.section_slopes(u, g)
    assert same["common_vs_distinct"]["p"] > 0.01
    assert min(same["cosine"].values()) > 0.99
    u[:, j[1]] = 0.3 * z[:, 1] + rng.normal(0, 0.01, 100)  # S2 follows the height instead
    other = landscape.section_slopes(u, g)
    assert other["common_vs_distinct"]["p"] < 1e-6
    assert abs(other["cosine"]["s1s2"]) < 0.1


def test_optimum_finds_a_known_per_target_optimum():
    """ToySim's reward peaks at rho1 = 3000 + 1000 (d - 0.5), anywhere in the other commands: the
    per-target optimum must reach that rho1 for each target, and two repeats agree."""
    from test_policy import ToySim

    ws = _workspace()
    T = search.Targets(targets.sample(ws, 6, 33, 180, 0.03), ws)
    spec = landscape.OptimumSpec(popsize=8, sigma0=0.3, generations=30, restarts=2)
    (u0, r0), (u1, r1) = (landscape.optimum(ToySim(), T, RANGES, spec, s, progress=False) for s in (1, 2))
    d = np.linalg.norm(T.p, axis=1)
    assert np.allclose(decode(u0, RANGES)["rho1"], 3000 + 1000 * (d - 0.5), atol=2.0)
    assert np.all(r0 > -0.002) and np.abs(r0 - r1).max() < 0.002


@pytest.mark.slow
def test_least_squares_fits_what_an_architecture_can_express():
    rng = np.random.default_rng(3)
    g = rng.normal(size=(60, 3))
    for arch in ("centralised", "shared"):
        th = networks.initial(arch, {"init": "glorot", "init_seed": 9}, 4)
        u = networks.outputs(arch, th, g)
        _, rms = landscape.fit_architecture(arch, g, u, 2, 7)
        assert rms < 0.02
    _, rms = landscape.fit_architecture("centralised", g, rng.uniform(-0.9, 0.9, (60, 6)), 1, 7)
    assert rms > 0.1  # noise it cannot express
