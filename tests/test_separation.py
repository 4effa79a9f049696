"""esnap check-separation: every kind of leak of docs/design.md section 3, injected and caught, on
the records and on a tiny Snakemake DAG; the policy is an allow list that names every rule."""

import json

import numpy as np
import pandas as pd
import pytest

from embodied_snap.lineage import records as pv
from embodied_snap.lineage.checks import check, check_dag, check_records, shard_source
from embodied_snap.lineage.policy import POLICY, may_feed

from lineage_tree import group_files as _files
from lineage_tree import write as _write

GROUPS = {  # group -> (evidence set, category, role in the split)
    "dyn_0001": ("dynamics", "free_space", "train"),
    "dyn_0002": ("dynamics", "target", "train"),
    "dyn_0003": ("dynamics", "pilot", "validation"),
    "dyn_0004": ("dynamics", "sealed", "sealed"),
    "dly_0001": ("delay_sweep", "sweep", "delay_sweep"),
}
SHARDS = {"dynamics_train-00": ["dyn_0001", "dyn_0002"], "dynamics_validation-00": ["dyn_0003"],
          "dynamics_sealed-00": ["dyn_0004"], "delay_sweep-00": ["dly_0001"]}


def _npz(root, role, ids):
    p = root / f"results/splits/windows_{role}.npz"
    p.parent.mkdir(parents=True, exist_ok=True)
    with open(p, "wb") as f:
        np.savez(f, x=np.zeros((len(ids), 3)), group_ids=np.array(ids))
    return f"results/splits/windows_{role}.npz"


def _run(root, split_role=None, shard_extra=None, truth_reader="twin_validation", windows_train=None,
         targets=None, raw="raw_data"):
    """A finished run as records: resample per shard, windows per role, GRU, sealed eval, gate, twin
    validation, policy targets, with recordings in `raw`. Keyword arguments inject the leaks."""
    split_role = {**{g: r for g, (_, _, r) in GROUPS.items()}, **(split_role or {})}
    _write(root, f"{raw}/index.csv", ("group_id,evidence_set,category,session\n" + "".join(
        f"{g},{es},{c},s01\n" for g, (es, c, _) in GROUPS.items())).encode())
    split = _write(root, "results/splits/split.csv", ("group_id,role\n" + "".join(
        f"{g},{r}\n" for g, r in split_role.items())).encode())
    pv.write_record("split", {}, [], [split], {}, "t", root=root)
    _write(root, f"{raw}/twin_truth.json", b"{}")
    rs = {}
    for shard, gs in SHARDS.items():
        gs = gs + (shard_extra or {}).get(shard, [])
        rs[shard] = _write(root, f"results/data/50hz/{shard}.parquet", shard.encode())
        pv.write_record("resample_shard", {"shard": shard}, [f for g in gs for f in _files(root, g, raw)],
                        [rs[shard]], {}, "t", root=root)
    w = {}
    for role in ("train", "validation", "sealed"):
        ids = windows_train if role == "train" and windows_train else \
            [g for s, gs in SHARDS.items() if s.startswith(f"dynamics_{role}-") for g in gs]
        w[role] = _npz(root, role, ids)
        pv.write_record("windows", {"role": role}, [rs[f"dynamics_{role}-00"]], [w[role]], {}, "t", root=root)
    m = _write(root, "results/dynamics/model.pt", b"m")
    pv.write_record("dynamics_train", {}, [w["train"], w["validation"]], [m], {}, "t", root=root)
    e = _write(root, "results/dynamics/sealed_eval.json", b"e")
    pv.write_record("dynamics_sealed_eval", {}, [m, w["sealed"]], [e], {}, "t", root=root)
    gate = _write(root, "results/dynamics/gate.json", b"g")
    pv.write_record("dynamics_gate", {}, [m, rs["delay_sweep-00"]], [gate], {}, "t", root=root)
    tv = _write(root, "results/twin/validation.json", b"v")
    pv.write_record(truth_reader, {}, [f"{raw}/twin_truth.json"], [tv], {}, "t", root=root)
    fig = _write(root, "results/figs/fig4_gates.png", b"f")
    pv.write_record("fig_gates", {}, [gate], [fig], {}, "t", root=root)
    tab = _write(root, "results/dynamics/claims.csv", b"c")
    pv.write_record("table_dynamics_claims", {}, [gate, e], [tab], {}, "t", root=root)
    t = targets or {"training": range(0, 48), "selection": range(100, 164), "evaluation": range(200, 600)}
    for name, ids in t.items():
        p = root / f"results/policy/targets_{name}.parquet"
        p.parent.mkdir(parents=True, exist_ok=True)
        pd.DataFrame({"target_id": list(ids)}).to_parquet(p)
    pv.write_record("policy_targets", {}, [], [f"results/policy/targets_{n}.parquet" for n in t], {}, "t", root=root)
    return root


def test_policy_table():
    assert shard_source("dynamics_sealed-03") == "sealed" and shard_source("delay_sweep-00") == "delay_sweep"
    assert not may_feed("delay_sweep", "dynamics_train", {})
    assert may_feed("delay_sweep", "dynamics_gate", {})
    assert not may_feed("sealed", "windows", {"role": "train"}) and may_feed("sealed", "windows", {"role": "sealed"})
    assert may_feed("sealed", "table_dynamics_claims", {}) and not may_feed("sealed", "fig_gates", {})
    assert not may_feed("servo_calibration", "policy_search", {}) and may_feed(
        "servo_calibration", "characterize_servo", {}
    )
    assert may_feed("sealed", "raw_manifest", {})  # bookkeeping carries no data onward
    # an allow list: a rule it does not name is fed by nothing, whatever its name looks like
    assert not may_feed("delay_sweep", "characterize_delay_sweep_extra", {})
    assert not may_feed("validation", "validate_sealed_copy", {})
    assert POLICY["sealed"].held_out and not POLICY["train"].held_out


def test_clean_run_passes(tmp_path):
    assert check_records(_run(tmp_path)) == []


def test_sealed_group_in_train_split(tmp_path):
    v = check_records(_run(tmp_path, split_role={"dyn_0004": "train"}))
    assert any("results/splits/split.csv puts sealed group dyn_0004 in train" in x for x in v), v
    assert all("\n" not in x for x in v)


def test_sealed_group_in_train_windows(tmp_path):
    v = check_records(_run(tmp_path, windows_train=["dyn_0001", "dyn_0002", "dyn_0004"]))
    assert v == [
        "separation (windows): results/splits/windows_train.npz holds group dyn_0004 of role sealed "
        "(results/splits/split.csv); docs/design.md 3: " + POLICY["sealed"].rule
    ]


def test_sealed_group_reaching_train_through_records(tmp_path):
    v = check_records(_run(tmp_path, shard_extra={"dynamics_train-00": ["dyn_0004"]}))
    # caught once, at the first job it must not reach, not again at the model downstream
    assert len(v) == 1 and "results/splits/windows_train.npz (rule windows(role=train))" in v[0]
    assert "sealed group dyn_0004" in v[0]


def test_delay_sweep_group_in_training_dataset(tmp_path):
    v = check_records(_run(tmp_path, shard_extra={"dynamics_train-00": ["dly_0001"]}))
    assert len(v) == 1, v
    assert v[0].startswith(
        "separation (records): results/splits/windows_train.npz (rule windows(role=train)) "
        "was fed by delay_sweep group dly_0001 through results/data/50hz/dynamics_train-00.parquet;"
    )
    assert POLICY["delay_sweep"].rule in v[0]


def test_evaluation_target_in_selection(tmp_path):
    v = check_records(
        _run(tmp_path, targets={"training": range(0, 48), "selection": [100, 101, 250], "evaluation": range(200, 600)})
    )
    assert v == [
        "separation (targets): results/policy/targets_selection.parquet shares 1 target(s) with "
        "targets_evaluation.parquet (first: 250); docs/design.md 3: training, selection, evaluation, offset "
        "and release targets are disjoint (separate seeds)"
    ]


def test_targets_by_position(tmp_path):
    _run(tmp_path)
    for name, xs in {"selection": [0.1, 0.2], "evaluation": [0.3, 0.2]}.items():
        pd.DataFrame({"x": xs, "y": [0.0, 0.0], "z": [0.5, 0.5]}).to_parquet(
            tmp_path / f"results/policy/targets_{name}.parquet"
        )
    v = check_records(tmp_path)
    assert len(v) == 1 and "targets_selection.parquet shares 1 target(s)" in v[0]


@pytest.mark.parametrize("reader", ["fig_twin", "raw_manifest"])  # bookkeeping may not read it either
def test_twin_truth_read_by_another_rule(tmp_path, reader):
    v = check_records(_run(tmp_path, truth_reader=reader))
    assert v == [
        f"separation (records): results/twin/validation.json (rule {reader}) read "
        "raw_data/twin_truth.json; docs/design.md 3: only twin_validation reads the simulated rig's ground truth"
    ]


# --- static: a tiny Snakefile, leaks switched on by config -----------------------------------------

SNAKEFILE = """
LEAK = config.get("leak", "")
SHARDS = {"train": ["dynamics_train-00"], "validation": ["dynamics_validation-00"], "sealed": ["dynamics_sealed-00"]}
if LEAK == "sealed_in_train":
    SHARDS["train"].append("dynamics_sealed-00")
ALL = ["dynamics_train-00", "dynamics_validation-00", "dynamics_sealed-00", "delay_sweep-00"]

rule all:
    input: "results/dynamics/claims.csv", "results/figures/fig4.png", "results/twin/validation.json",
           "results/policy/eval/shared_seed0.parquet", "results/ablation/rules.parquet",
           ["results/dynamics/model_finetuned.pt"] if LEAK == "unnamed" else []

rule twin_acquire:
    output: "raw_data/shards/{shard}.done"

rule twin_truth:
    output: "raw_data/twin_truth.json"

rule validate_shard:
    input: "raw_data/shards/{shard}.done"
    output: "results/raw/shards/{shard}.json"

rule raw_manifest:
    input: expand("results/raw/shards/{s}.json", s=ALL)
    output: "results/raw/manifest.json"

rule resample_shard:
    input: "raw_data/shards/{shard}.done", "results/raw/manifest.json"
    output: "results/data/50hz/{shard}.parquet"

rule windows:
    input: lambda wc: expand("results/data/50hz/{s}.parquet", s=SHARDS[wc.role])
    output: "results/splits/windows_{role}.npz"

rule dynamics_train:
    input:
        "results/splits/windows_train.npz",
        "results/splits/windows_validation.npz",
        ["results/data/50hz/delay_sweep-00.parquet"] if LEAK == "delay" else [],
        ["raw_data/twin_truth.json"] if LEAK == "truth" else [],
        ["raw_data/groups/dly_0001/mocap.parquet"] if LEAK == "direct" else [],
        ["results/raw/sealed_copy.json"] if LEAK == "validate_named" else [],
    output: "results/dynamics/model.pt"

rule characterize_delay_sweep:
    input: "raw_data/groups/dly_0001/mocap.parquet"
    output: "results/characterize/delay_sweep.json"

rule dynamics_sealed_eval:
    input: "results/dynamics/model.pt", "results/splits/windows_sealed.npz"
    output: "results/dynamics/sealed_eval.json"

rule dynamics_gate:
    input: "results/dynamics/model.pt", "results/data/50hz/delay_sweep-00.parquet"
    output: "results/dynamics/gate.json"

rule twin_validation:
    input: "raw_data/twin_truth.json"
    output: "results/twin/validation.json"

rule policy_targets:
    output: expand("results/policy/targets_{s}.parquet", s=("training", "selection", "evaluation"))

rule policy_search:
    input:
        "results/dynamics/model.pt", "results/policy/targets_training.parquet",
        "results/policy/targets_selection.parquet",
        ["results/policy/targets_evaluation.parquet"] if LEAK == "evaluation_targets" else [],
    output: "results/policy/runs/shared_seed0.json"

rule policy_evaluate:
    input: "results/policy/runs/shared_seed0.json", "results/policy/targets_evaluation.parquet"
    output: "results/policy/eval/shared_seed0.parquet"

rule ablation_targets:
    output: expand("results/ablation/targets_{s}.parquet", s=("offset", "release"))

rule ablation_offsets:
    input:
        "results/policy/runs/shared_seed0.json", "results/ablation/targets_offset.parquet",
        ["results/ablation/targets_release.parquet"] if LEAK == "release_targets" else [],
    output: "results/ablation/offsets.json"

rule ablation_rules:
    input: "results/ablation/offsets.json", "results/ablation/targets_release.parquet"
    output: "results/ablation/rules.parquet"

rule fig_gates:
    input: "results/dynamics/gate.json", "results/characterize/delay_sweep.json"
    output: "results/figures/fig4.png"

rule table_dynamics_claims:
    input: "results/dynamics/gate.json", "results/dynamics/sealed_eval.json"
    output: "results/dynamics/claims.csv"

if LEAK == "unnamed":
    rule gru_finetune:
        input: "results/dynamics/model.pt", "results/data/50hz/delay_sweep-00.parquet"
        output: "results/dynamics/model_finetuned.pt"

if LEAK == "validate_named":
    rule validate_sealed_copy:
        input: "results/data/50hz/dynamics_sealed-00.parquet"
        output: "results/raw/sealed_copy.json"
"""


@pytest.fixture
def wf(tmp_path):
    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    # a recording that rules read directly, classified by the index
    _write(tmp_path, "raw_data/index.csv", b"group_id,evidence_set,category,session\ndly_0001,delay_sweep,sweep,s01\n")
    _write(tmp_path, "raw_data/groups/dly_0001/mocap.parquet")
    return tmp_path


def test_dag_clean(wf):
    assert check_dag(wf) == []


def test_dag_delay_sweep_in_training(wf):
    v = check_dag(wf, config_overrides={"leak": "delay"})
    assert v == [
        "separation (DAG): results/dynamics/model.pt (rule dynamics_train) is reachable from delay_sweep "
        "shard delay_sweep-00 via resample_shard(shard=delay_sweep-00) > dynamics_train; docs/design.md 3: "
        + POLICY["delay_sweep"].rule
    ]


def test_dag_sealed_shard_in_train_windows(wf):
    v = check_dag(wf, config_overrides={"leak": "sealed_in_train"})
    assert len(v) == 1 and v[0].startswith(
        "separation (DAG): results/splits/windows_train.npz (rule windows(role=train)) is reachable from sealed shard "
        "dynamics_sealed-00 via resample_shard(shard=dynamics_sealed-00) > windows(role=train)"
    )


def test_dag_twin_truth_read_by_another_rule(wf):
    v = check_dag(wf, config_overrides={"leak": "truth"})
    assert v == [
        "separation (DAG): results/dynamics/model.pt (rule dynamics_train) reads raw_data/twin_truth.json; "
        "docs/design.md 3: " + POLICY["twin_truth"].rule
    ]


def test_dag_evaluation_targets_read_by_the_search(wf):
    v = check_dag(wf, config_overrides={"leak": "evaluation_targets"})
    assert v == [
        "separation (DAG): results/policy/runs/shared_seed0.json (rule policy_search) reads "
        "results/policy/targets_evaluation.parquet; docs/design.md 3: "
        + POLICY["results/policy/targets_evaluation.parquet"].rule
    ]


def test_dag_release_targets_read_by_the_offset_fit(wf):
    v = check_dag(wf, config_overrides={"leak": "release_targets"})
    assert v == [
        "separation (DAG): results/ablation/offsets.json (rule ablation_offsets) reads "
        "results/ablation/targets_release.parquet; docs/design.md 3: "
        + POLICY["results/ablation/targets_release.parquet"].rule
    ]


def test_dag_release_targets_reach_no_offset_fit():
    # the offsets feed the rule comparison, never the other way round
    rel = "results/ablation/targets_release.parquet"
    assert not may_feed(rel, "ablation_offsets", {}) and may_feed(rel, "ablation_rules", {})
    assert POLICY[rel].readers == ("ablation_rules", "check_separation") and POLICY[rel].held_out
    off = "results/ablation/targets_offset.parquet"
    assert POLICY[off].readers == ("ablation_offsets", "check_separation")


def _ablation_targets(root, offset, release, leak=False):
    for name, ids in {"offset": offset, "release": release}.items():
        p = root / f"results/ablation/targets_{name}.parquet"
        p.parent.mkdir(parents=True, exist_ok=True)
        pd.DataFrame({"target_id": list(ids)}).to_parquet(p)
    files = [f"results/ablation/targets_{n}.parquet" for n in ("offset", "release")]
    pv.write_record("ablation_targets", {}, [], files, {}, "t", root=root)
    o = _write(root, "results/ablation/offsets.json", b"o")
    pv.write_record("ablation_offsets", {}, files if leak else files[:1], [o], {}, "t", root=root)
    return root


def test_records_ablation_targets_disjoint(tmp_path):
    assert check_records(_ablation_targets(_run(tmp_path), range(1000, 1100), range(2000, 2400))) == []


def test_records_release_target_in_offset_set(tmp_path):
    v = check_records(_ablation_targets(_run(tmp_path), [1000, 2005], range(2000, 2400)))
    assert v == [
        "separation (targets): results/ablation/targets_release.parquet shares 1 target(s) with "
        "targets_offset.parquet (first: 2005); docs/design.md 3: training, selection, evaluation, offset "
        "and release targets are disjoint (separate seeds)"
    ]


def test_records_release_targets_read_by_the_offset_fit(tmp_path):
    v = check_records(_ablation_targets(_run(tmp_path), range(1000, 1100), range(2000, 2400), leak=True))
    assert v == [
        "separation (records): results/ablation/offsets.json (rule ablation_offsets) read "
        "results/ablation/targets_release.parquet; docs/design.md 3: "
        + POLICY["results/ablation/targets_release.parquet"].rule
    ]


def test_records_offset_target_in_evaluation_set(tmp_path):
    v = check_records(_ablation_targets(_run(tmp_path), [1000, 250], range(2000, 2400)))
    assert len(v) == 1 and "results/policy/targets_evaluation.parquet shares 1 target(s) with targets_offset" in v[0]


def test_dag_delay_sweep_recording_read_directly(wf):
    v = check_dag(wf, config_overrides={"leak": "direct"})
    assert v == [
        "separation (DAG): results/dynamics/model.pt (rule dynamics_train) reads raw delay_sweep group "
        "dly_0001; docs/design.md 3: " + POLICY["delay_sweep"].rule
    ]


def test_check_both(wf):
    _run(wf, shard_extra={"dynamics_train-00": ["dly_0001"]})
    r = check(wf, config_overrides={"leak": "delay"})
    assert not r["ok"] and len(r["violations"]) == 2
    assert r["checked"]["dag_jobs"] > 10 and r["checked"]["records"] == 15 and r["checked"]["groups"] == 5
    assert check(wf)["ok"] is False  # the records still hold the leak
    assert check(wf, records=False)["ok"] is True
    bad = check(wf, records=False, config_overrides={"leak": "delay"}, targets=("no_such_rule",))
    assert not bad["ok"] and "could not build the Snakemake DAG" in bad["violations"][0]


def test_dag_rule_without_policy_entry(wf):
    """A new rule (fine-tuning the model on the delay sweep) is refused because nothing names it."""
    v = check_dag(wf, config_overrides={"leak": "unnamed"})
    assert v[0] == (
        "separation (policy): results/dynamics/model_finetuned.pt (rule gru_finetune) is named by no "
        "entry of the policy; docs/design.md 3: every rule says what it may be fed "
        "(embodied_snap/lineage/policy.py)"
    )
    assert any("(rule gru_finetune) is reachable from delay_sweep shard delay_sweep-00" in x for x in v), v


def test_dag_validate_named_rule_carrying_sealed_data(wf):
    """A rule named like the validation bookkeeping gets no exemption: sealed data reaching
    training through it is caught."""
    v = check_dag(wf, config_overrides={"leak": "validate_named"})
    assert any("(rule validate_sealed_copy) is named by no entry" in x for x in v), v
    assert any("(rule validate_sealed_copy) is reachable from sealed shard dynamics_sealed-00" in x for x in v), v


def test_records_deleted_record_is_a_violation(tmp_path):
    _run(tmp_path)
    (tmp_path / "results/provenance/windows/role=train.json").unlink()
    v = check_records(tmp_path)
    assert (
        "separation (records): results/splits/windows_train.npz (read by rule dynamics_train) has no "
        "provenance record; docs/design.md 3: every result has a readable provenance record"
    ) in v
    assert (
        "separation (records): results/splits/windows_train.npz has no provenance record; "
        "docs/design.md 3: every result has a readable provenance record"
    ) in v


def test_records_unreadable_record_is_a_violation(tmp_path):
    _run(tmp_path)
    (tmp_path / "results/provenance/dynamics_sealed_eval/_.json").write_text("{not json")
    v = check_records(tmp_path)
    assert v and v[0].startswith(
        "separation (records): results/provenance/dynamics_sealed_eval/_.json cannot be read (JSONDecodeError"
    )


def test_records_in_another_raw_directory(tmp_path):
    """Recordings outside raw_data/ (raw_data.dir in config) are classified all the same."""
    _run(tmp_path, shard_extra={"dynamics_train-00": ["dly_0001"]}, raw="recordings/lab2")
    v = check_records(tmp_path, raw="recordings/lab2")
    assert len(v) == 1 and "was fed by delay_sweep group dly_0001" in v[0]
    # through check(): the raw directory comes from the config given
    r = check(tmp_path, static=False, config_overrides={"raw_data": {"dir": "recordings/lab2"}})
    assert r["violations"] == v and r["raw_dir"] == "recordings/lab2"


def test_records_from_several_hosts(tmp_path):
    """A cluster run: the records of one run name several hosts (each job's node); the proof reads
    them all alike, and still finds a leak."""
    _run(tmp_path)
    recs = sorted((tmp_path / pv.RECORDS_DIR).glob("*/*.json"))
    for i, f in enumerate(recs):
        rec = json.loads(f.read_text())
        rec["host"] = f"node-{i % 3}"
        f.write_text(json.dumps(rec))
    assert check(tmp_path, static=False, config_overrides={})["ok"]
    _run(tmp_path / "leak", shard_extra={"dynamics_train-00": ["dly_0001"]})
    for i, f in enumerate(sorted((tmp_path / "leak" / pv.RECORDS_DIR).glob("*/*.json"))):
        rec = json.loads(f.read_text())
        rec["host"] = f"node-{i % 3}"
        f.write_text(json.dumps(rec))
    v = check(tmp_path / "leak", static=False, config_overrides={})["violations"]
    assert len(v) == 1 and "was fed by delay_sweep group dly_0001" in v[0]
