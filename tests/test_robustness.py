"""Robustness of the architecture benchmark (issue 12, item 5): a smaller budget is exactly the run
stopped there, a larger one exactly the run continued, uniform workspace targets, rankings and claims."""

import numpy as np
import pytest
from test_policy import RANGES, ToySim, _workspace

from embodied_snap import bearing as BR
from embodied_snap.policy import geometry, robustness, search, targets
from embodied_snap.reference import paper_column, paper_values

N = np.array([0.0, -1.0, 0.0])


def _run(generations, snapshots=(), resume=None, tr=None):
    ws = _workspace()
    tr = targets.sample(ws, 8 * 8, 11, 180, 0.03) if tr is None else tr
    gen = np.arange(len(tr)) // 8
    train, sel = search.Targets(tr, ws), search.Targets(targets.sample(ws, 16, 22, 180, 0.03), ws)
    tgt = search.SearchTargets(train=train, gen_of=gen, select=sel, norm=search.feature_stats(train))
    spec = search.SearchSpec(ranges=RANGES, generations=generations, popsize=6, start=dict(init="zero", sigma0=0.5),
                             snapshots=snapshots)
    return search.cmaes(ToySim(), "shared", 0, tgt, spec, progress=False, resume=resume)


def _same(a, b):
    keys = ("curve", "theta", "selection_reward", "selected_generation", "final_heldout_reward")
    return all(a[k] == b[k] for k in keys)


def test_a_smaller_budget_is_the_run_stopped_there():
    """CMA-ES does not depend on its total budget: the snapshot at 4 of 8 generations is the 4-generation
    run, byte for byte."""
    long, short = _run(8, snapshots=[4]), _run(4)
    assert _same(search.at_budget(long, 4), short)
    assert not _same(long, short)


def test_a_larger_budget_is_the_run_continued():
    """Continuing a 4-generation run from its state to 8 generations gives the 8-generation run, in
    a fresh process too (pycma samples from numpy's global random state: the state carries it)."""
    short = _run(4)
    np.random.seed(12345)  # what another process would start with
    assert _same(_run(8, resume=short), _run(8))


def test_uniform_targets_fill_the_strike_region():
    ws = _workspace()
    a = targets.sample_uniform(ws, 300, 66, 180)
    assert a.equals(targets.sample_uniform(ws, 300, 66, 180)) and a.target_id.is_unique
    assert not set(a.target_id) & set(targets.sample_uniform(ws, 300, 77, 180).target_id)
    rh = targets.radius_height(a[["x", "y", "z"]].to_numpy(), N)
    cloud = targets.radius_height(np.asarray(ws["strike_points_m"]), N)
    assert np.all(rh >= cloud.min(0) - 1e-9) and np.all(rh <= cloud.max(0) + 1e-9)
    # uniform, not clustered about the strikes: the heights spread like a uniform draw over the range
    lo, hi = cloud[:, 1].min(), cloud[:, 1].max()
    assert np.std(rh[:, 1]) > 0.8 * (hi - lo) / np.sqrt(12) * 0.7
    assert np.allclose(np.linalg.norm(a[["nx", "ny", "nz"]], axis=1), 1)
    # the features are the policy's: rotation about the hanging axis leaves them unchanged
    p = a[["x", "y", "z"]].to_numpy()
    assert np.allclose(geometry.features(p, N), geometry.features(BR.rotate(p, 37.0, N), N))


def _variant(rewards: dict, attach: dict) -> dict:
    return dict(archs=list(rewards), generations=10,
                reward={a: dict(mean=np.mean(v), sd=np.std(v, ddof=1), n=len(v)) for a, v in rewards.items()},
                attachment_report={a: dict(mean=m, sd=0.01) for a, m in attach.items()},
                reward_tests={"centralised": dict(p=0.01)})


def test_rankings_and_whether_they_hold():
    base = _variant({"shared": [0.5, 0.6], "centralised": [0.3, 0.4]}, {"shared": 0.7, "centralised": 0.6})
    flip = _variant({"shared": [0.3, 0.4], "centralised": [0.5, 0.6]}, {"shared": 0.7, "centralised": 0.6})
    out = {}
    for v, x in (("benchmark", base), ("uniform", flip)):
        x["ranking_reward"] = robustness.ranking({a: r["mean"] for a, r in x["reward"].items()})
        x["ranking_attachment"] = robustness.ranking({a: r["mean"] for a, r in x["attachment_report"].items()})
        x["ranking_reward_holds"] = x["ranking_reward"] == base["ranking_reward"]
        x["ranking_attachment_holds"] = x["ranking_attachment"] == base["ranking_attachment"]
        out[v] = x
    assert out["uniform"]["ranking_reward"] == ["centralised", "shared"]
    assert robustness.ranking({"a": 0.0, "b": 0.5, "c": 0.0}) == ["b", "a = c"]
    rows = {r["claim_id"]: r for r in robustness.claim_rows(out, paper_column("policy"))}
    assert rows["uniform.ranking_reward_holds"]["ours"] == "no"
    assert rows["benchmark.ranking_reward_holds"]["ours"] == "yes"
    assert rows["uniform.ranking_attach_5cm_holds"]["ours"] == "yes"
    # the paper's ranking is derived from its values, never typed
    ref = paper_values()["policy"]
    assert rows["benchmark.ranking_reward"]["paper"] == " > ".join(
        sorted((a for a in ("shared", "centralised") if f"reward_{a}_mean" in ref),
               key=lambda a: -ref[f"reward_{a}_mean"]["paper"]))
    assert rows["benchmark.reward_shared"]["paper"] == f"[{ref['reward_shared_mean']['paper']:.4g}, " \
                                                       f"{ref['reward_shared_sd']['paper']:.4g}]"


def test_correlations_known_answer_distance_and_radius_disagree_in_sign():
    """analysis.correlations on three targets whose centred columns are multiples of a = (-1, 0, 1),
    b = (-1, 1, 0) or c = (0, -1, 1): the Pearson r of two such columns is their cosine, +-1 or
    +-1/2 (a.b = a.c = 1, b.c = -1, each of norm sqrt 2). The target rises (e ~ a) while its distance
    falls (d ~ -a) and its radius grows (r ~ b), as on the reach shell (docs/policy.md); rho3 ~ b,
    rho2 ~ a, tau ~ -b, dphi ~ c. Known answer: r(d, e) = -1; rho3: height +1/2, distance -1/2,
    radius +1; rho2: distance -1, radius +1/2; tau: distance +1/2, radius -1; dphi: height +1/2.
    The signs with distance are opposite to those with radius, and each value names its pair."""
    import pandas as pd

    from embodied_snap.policy.analysis import correlations

    a, b, c = np.array([-1.0, 0, 1]), np.array([-1.0, 1, 0]), np.array([0.0, -1, 1])
    df = pd.DataFrame(dict(e_m=-0.80 + 0.05 * a, d_m=0.80 - 0.04 * a, r_m=0.30 + 0.1 * b, rho3=2900 + 200 * b,
                           rho2=2700 + 150 * a, tau_s=0.55 - 0.05 * b, dphi_deg=3.0 * c))
    assert correlations(df) == pytest.approx(dict(
        targets_distance_height=-1.0, rho3_height=0.5, rho3_distance=-0.5, rho3_radius=1.0,
        rho2_distance=-1.0, rho2_radius=0.5, tau_distance=0.5, tau_radius=-1.0, dphi_height=0.5), abs=1e-9)
