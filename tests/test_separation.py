"""esnap check-separation: every kind of leak of DESIGN section 3, injected and caught, on the
records and on a tiny Snakemake DAG."""

import numpy as np
import pandas as pd
import pytest

from embodied_snap.lineage import records as pv
from embodied_snap.lineage.checks import POLICY, check, check_dag, check_records, forbidden, shard_source

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
         targets=None):
    """A finished run as records: resample per shard, windows per role, GRU, sealed eval, gate, twin
    validation, policy targets. Keyword arguments inject the leaks."""
    split_role = {**{g: r for g, (_, _, r) in GROUPS.items()}, **(split_role or {})}
    _write(root, "raw_data/index.csv", ("group_id,evidence_set,category,session\n" + "".join(
        f"{g},{es},{c},s01\n" for g, (es, c, _) in GROUPS.items())).encode())
    _write(root, "results/splits/split.csv", ("group_id,role\n" + "".join(
        f"{g},{r}\n" for g, r in split_role.items())).encode())
    _write(root, "raw_data/twin_truth.json", b"{}")
    rs = {}
    for shard, gs in SHARDS.items():
        gs = gs + (shard_extra or {}).get(shard, [])
        rs[shard] = _write(root, f"results/data/50hz/{shard}.parquet", shard.encode())
        pv.write_record("resample_shard", {"shard": shard}, [f for g in gs for f in _files(root, g)],
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
    pv.write_record(truth_reader, {}, ["raw_data/twin_truth.json"], [tv], {}, "t", root=root)
    fig = _write(root, "results/figures/fig4.png", b"f")
    pv.write_record("fig_gate", {}, [gate, e, tv], [fig], {}, "t", root=root)
    t = targets or {"training": range(0, 48), "selection": range(100, 164), "evaluation": range(200, 600)}
    for name, ids in t.items():
        p = root / f"results/policy/targets_{name}.parquet"
        p.parent.mkdir(parents=True, exist_ok=True)
        pd.DataFrame({"target_id": list(ids)}).to_parquet(p)
    return root


def test_policy_table():
    assert shard_source("dynamics_sealed-03") == "sealed" and shard_source("delay_sweep-00") == "delay_sweep"
    assert forbidden("delay_sweep", "dynamics_train", {})
    assert not forbidden("delay_sweep", "dynamics_gate", {})
    assert forbidden("sealed", "windows", {"role": "train"}) and not forbidden("sealed", "windows", {"role": "sealed"})
    assert forbidden("sealed", "policy_cmaes", {}) and not forbidden("sealed", "table_claims", {})
    assert forbidden("servo_calibration", "policy_search", {}) and not forbidden("servo_calibration", "characterize_servo", {})
    assert not forbidden("sealed", "raw_manifest", {})  # bookkeeping is allowed everywhere
    assert POLICY["sealed"]["held_out"] and not POLICY["train"]["held_out"]


def test_clean_run_passes(tmp_path):
    assert check_records(_run(tmp_path)) == []


def test_sealed_group_in_train_split(tmp_path):
    v = check_records(_run(tmp_path, split_role={"dyn_0004": "train"}))
    assert any("results/splits/split.csv puts sealed group dyn_0004 in train" in x for x in v), v
    assert all("\n" not in x for x in v)


def test_sealed_group_in_train_windows(tmp_path):
    v = check_records(_run(tmp_path, windows_train=["dyn_0001", "dyn_0002", "dyn_0004"]))
    assert v == ["separation (windows): results/splits/windows_train.npz holds group dyn_0004 of role sealed "
                 "(results/splits/split.csv); DESIGN 3: " + POLICY["sealed"]["rule"]]


def test_sealed_group_reaching_train_through_records(tmp_path):
    v = check_records(_run(tmp_path, shard_extra={"dynamics_train-00": ["dyn_0004"]}))
    # caught once, at the first job it must not reach, not again at the model downstream
    assert len(v) == 1 and "results/splits/windows_train.npz (rule windows(role=train))" in v[0]
    assert "sealed group dyn_0004" in v[0]


def test_delay_sweep_group_in_training_dataset(tmp_path):
    v = check_records(_run(tmp_path, shard_extra={"dynamics_train-00": ["dly_0001"]}))
    assert len(v) == 1, v
    assert v[0].startswith("separation (records): results/splits/windows_train.npz (rule windows(role=train)) "
                           "was fed by delay_sweep group dly_0001 through results/data/50hz/dynamics_train-00.parquet;")
    assert POLICY["delay_sweep"]["rule"] in v[0]


def test_evaluation_target_in_selection(tmp_path):
    v = check_records(_run(tmp_path, targets={"training": range(0, 48), "selection": [100, 101, 250],
                                              "evaluation": range(200, 600)}))
    assert v == ["separation (targets): results/policy/targets_selection.parquet shares 1 target(s) with "
                 "targets_evaluation.parquet (first: 250); DESIGN 3: training, selection and evaluation "
                 "targets are disjoint (separate seeds)"]


def test_targets_by_position(tmp_path):
    _run(tmp_path)
    for name, xs in {"selection": [0.1, 0.2], "evaluation": [0.3, 0.2]}.items():
        pd.DataFrame({"x": xs, "y": [0.0, 0.0], "z": [0.5, 0.5]}).to_parquet(
            tmp_path / f"results/policy/targets_{name}.parquet")
    v = check_records(tmp_path)
    assert len(v) == 1 and "targets_selection.parquet shares 1 target(s)" in v[0]


@pytest.mark.parametrize("reader", ["fig_twin", "raw_manifest"])  # bookkeeping may not read it either
def test_twin_truth_read_by_another_rule(tmp_path, reader):
    v = check_records(_run(tmp_path, truth_reader=reader))
    assert v == [f"separation (records): results/twin/validation.json (rule {reader}) read "
                 "raw_data/twin_truth.json; DESIGN 3: only twin_validation reads the simulated rig's ground truth"]


# --- static: a tiny Snakefile, leaks switched on by config -----------------------------------------

SNAKEFILE = '''
LEAK = config.get("leak", "")
SHARDS = {"train": ["dynamics_train-00"], "validation": ["dynamics_validation-00"], "sealed": ["dynamics_sealed-00"]}
if LEAK == "sealed_in_train":
    SHARDS["train"].append("dynamics_sealed-00")
ALL = ["dynamics_train-00", "dynamics_validation-00", "dynamics_sealed-00", "delay_sweep-00"]

rule all:
    input: "results/dynamics/sealed_eval.json", "results/dynamics/gate.json", "results/figures/fig4.png",
           "results/policy/eval/shared_seed0.parquet"

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

rule fig_gate:
    input: "results/dynamics/gate.json", "results/characterize/delay_sweep.json", "results/twin/validation.json", "results/dynamics/sealed_eval.json"
    output: "results/figures/fig4.png"
'''


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
    assert v == ["separation (DAG): results/dynamics/model.pt (rule dynamics_train) is reachable from delay_sweep "
                 "shard delay_sweep-00 via resample_shard(shard=delay_sweep-00) > dynamics_train; DESIGN 3: "
                 + POLICY["delay_sweep"]["rule"]]


def test_dag_sealed_shard_in_train_windows(wf):
    v = check_dag(wf, config_overrides={"leak": "sealed_in_train"})
    assert len(v) == 1 and v[0].startswith(
        "separation (DAG): results/splits/windows_train.npz (rule windows(role=train)) is reachable from sealed shard "
        "dynamics_sealed-00 via resample_shard(shard=dynamics_sealed-00) > windows(role=train)")


def test_dag_twin_truth_read_by_another_rule(wf):
    v = check_dag(wf, config_overrides={"leak": "truth"})
    assert v == ["separation (DAG): results/dynamics/model.pt (rule dynamics_train) reads raw_data/twin_truth.json; "
                 "DESIGN 3: " + POLICY["raw_data/twin_truth.json"]["rule"]]


def test_dag_evaluation_targets_read_by_the_search(wf):
    v = check_dag(wf, config_overrides={"leak": "evaluation_targets"})
    assert v == ["separation (DAG): results/policy/runs/shared_seed0.json (rule policy_search) reads "
                 "results/policy/targets_evaluation.parquet; DESIGN 3: "
                 + POLICY["results/policy/targets_evaluation.parquet"]["rule"]]


def test_dag_delay_sweep_recording_read_directly(wf):
    v = check_dag(wf, config_overrides={"leak": "direct"})
    assert v == ["separation (DAG): results/dynamics/model.pt (rule dynamics_train) reads raw delay_sweep group "
                 "dly_0001; DESIGN 3: " + POLICY["delay_sweep"]["rule"]]


def test_check_both(wf):
    _run(wf, shard_extra={"dynamics_train-00": ["dly_0001"]})
    r = check(wf, config_overrides={"leak": "delay"})
    assert not r["ok"] and len(r["violations"]) == 2
    assert r["checked"]["dag_jobs"] > 10 and r["checked"]["records"] == 12 and r["checked"]["groups"] == 5
    assert check(wf)["ok"] is False  # the records still hold the leak
    assert check(wf, records=False)["ok"] is True
    bad = check(wf, records=False, config_overrides={"leak": "delay"}, targets=("no_such_rule",))
    assert not bad["ok"] and "could not build the Snakemake DAG" in bad["violations"][0]
