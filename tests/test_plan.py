"""The group plan: paper counts, the 440/78/20 split by group, role-pure shards, rig index checks."""

import pandas as pd
import pytest
import yaml

from embodied_snap.plan import PlanError, assign_roles, load_plan, rig_plan, shard, twin_plan

CFG = yaml.safe_load(open("config.yaml"))


def plan(budget="paper", **kw):
    cfg = {**CFG, "budget": budget, **kw}
    return load_plan(cfg)


def test_paper_counts_match_table_I():
    p = plan()
    n = p.groupby("evidence_set").size().to_dict()
    assert n["servo_calibration"] == 291 and n["attachment"] == 90 and n["delay_sweep"] == 33
    assert n["dynamics"] == 538 and n["held_base"] == 133
    assert (p[p.evidence_set == "release_mode"].category == "instantaneous").sum() == 59
    dyn = p[p.evidence_set == "dynamics"].category.value_counts().to_dict()
    assert dyn == {"free_space": 203, "target": 76, "sealed": 20, "pilot": 28, "characterisation": 211}


def test_split_is_440_78_20_and_sealed_is_the_sealed_category():
    p = plan()
    assert p.role.value_counts()[["train", "validation", "sealed"]].tolist() == [440, 78, 20]
    assert set(p[p.role == "sealed"].category) == {"sealed"}
    assert not (p[p.role != "sealed"].category == "sealed").any()


def test_split_is_seeded_and_depends_on_seed():
    a, b = plan(), plan()
    pd.testing.assert_frame_equal(a, b)
    c = plan(seed=CFG["seed"] + 1)
    assert set(a[a.role == "validation"].group_id) != set(c[c.role == "validation"].group_id)


def test_shards_never_mix_evidence_sets_or_splits():
    p = plan()
    per_shard = p.groupby("shard").agg(
        sets=("evidence_set", "nunique"), roles=("role", "nunique"), n=("group_id", "size")
    )
    assert (per_shard.sets == 1).all() and (per_shard.roles == 1).all()
    assert per_shard.n.max() <= CFG["budgets"]["paper"]["shard_size"]
    assert p.group_id.is_unique


def test_validation_larger_than_pool_is_refused():
    g = twin_plan({"dynamics": {"free_space": 3, "sealed": 1}}, 2)
    with pytest.raises(PlanError, match="rule: split sizes"):
        assign_roles(g, 3, 0)


@pytest.mark.parametrize(
    "rows, rule",
    [
        ([("att_0001", "attachment"), ("att_0001", "attachment")], "unique group_id"),
        ([("xyz_0001", "wibble")], "known evidence set"),
        ([("../../x", "attachment")], "group id pattern"),
    ],
)
def test_rig_index_errors_are_one_line_and_name_group_and_rule(tmp_path, rows, rule):
    f = tmp_path / "index.csv"
    pd.DataFrame(
        [
            dict(
                group_id=g,
                evidence_set=e,
                category="target",
                session="s01",
                recorded_at="2026-03-01T10:00:00Z",
                n_mocap=1,
                n_servo=1,
            )
            for g, e in rows
        ]
    ).to_csv(f, index=False)
    with pytest.raises(PlanError) as e:
        rig_plan(f)
    msg = str(e.value)
    assert "\n" not in msg and str(f) in msg and rows[0][0] in msg and rule in msg


def test_rig_plan_missing_index(tmp_path):
    with pytest.raises(PlanError, match="index.csv: group -: missing"):
        rig_plan(tmp_path / "index.csv")


def test_shard_names_carry_the_split_for_dynamics():
    p = shard(
        assign_roles(twin_plan({"dynamics": {"free_space": 10, "sealed": 2}, "attachment": {"target": 3}}, 2), 2, 1), 4
    )
    assert set(p[p.role == "sealed"].shard) == {"dynamics_sealed-00"}
    assert set(p[p.evidence_set == "attachment"].shard) == {"attachment-00"}
    assert set(p[p.role == "train"].shard) == {"dynamics_train-00", "dynamics_train-01"}
