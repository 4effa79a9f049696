"""PROV-JSON export: entities, activities, usage/generation, groups as collections with held-out status."""

import json

from prov.model import ProvDocument

from embodied_snap.lineage import records as pv
from embodied_snap.lineage.policy import held_out
from embodied_snap.lineage.prov import NAMESPACES, export

from lineage_tree import group_files as _files
from lineage_tree import write as _write


def test_export(tmp_path):
    _write(tmp_path, "raw_data/index.csv", b"group_id,evidence_set,category,session\n"
           b"dyn_0001,dynamics,free_space,s01\ndyn_0002,dynamics,sealed,s02\n"
           b"dly_0001,delay_sweep,sweep,s01\ncal_0001,servo_calibration,burst,s01\n")
    _write(tmp_path, "results/splits/split.csv", b"group_id,role\ndyn_0001,train\ndyn_0002,sealed\n")
    _files(tmp_path, "cal_0001")  # on disk, never used by a recorded job
    code = _write(tmp_path, "embodied_snap/plan.py", b"# plan")
    o = _write(tmp_path, "results/data/50hz/dynamics_train-00.parquet", b"o")
    pv.write_record("resample_shard", {"shard": "dynamics_train-00"}, _files(tmp_path, "dyn_0001") + [code],
                    [o], {"hz": 50}, "2026-11-23T10:00:00+00:00", root=tmp_path)
    w = _write(tmp_path, "results/splits/windows_train.npz", b"w")
    pv.write_record("windows", {"role": "train"}, [o], [w], {}, "2026-11-23T10:01:00+00:00", root=tmp_path)
    out = export(tmp_path)
    assert out == tmp_path / "results/lineage/prov.json"
    d = json.loads(out.read_text())

    assert {k: d["prefix"][k] for k in NAMESPACES} == NAMESPACES
    mocap = d["entity"]["file:raw_data/groups/dyn_0001/mocap.parquet"]
    assert mocap["esnap:sha256"] == pv.sha256(tmp_path / "raw_data/groups/dyn_0001/mocap.parquet")
    assert d["entity"]["file:embodied_snap/plan.py"]["prov:type"]["$"] == "esnap:Code"
    acts = d["activity"]
    assert set(acts) == {"job:resample_shard/shard=dynamics_train-00", "job:windows/role=train"}
    assert acts["job:windows/role=train"]["esnap:rule"] == "windows"
    assert acts["job:windows/role=train"]["prov:startTime"].startswith("2026-11-23T10:01:00")
    used = {(u["prov:activity"], u["prov:entity"]) for u in d["used"].values()}
    assert ("job:windows/role=train", "file:results/data/50hz/dynamics_train-00.parquet") in used
    gen = {(g["prov:entity"], g["prov:activity"]) for g in d["wasGeneratedBy"].values()}
    assert ("file:results/splits/windows_train.npz", "job:windows/role=train") in gen

    colls = {k: v for k, v in d["entity"].items() if k.startswith("group:")}
    assert set(colls) == {"group:dyn_0001", "group:dyn_0002", "group:dly_0001", "group:cal_0001"}
    assert all(v["prov:type"]["$"] == "prov:Collection" for v in colls.values())
    assert colls["group:dyn_0001"]["esnap:role"] == "train" and colls["group:dyn_0001"]["esnap:held_out"] is False
    assert colls["group:dyn_0002"]["esnap:held_out"] is True  # sealed
    assert colls["group:dly_0001"]["esnap:held_out"] is True  # delay sweep: never any model fit
    assert colls["group:dly_0001"]["esnap:evidence_set"] == "delay_sweep"
    members = {(m["prov:collection"], m["prov:entity"]) for m in d["hadMember"].values()}
    assert ("group:dyn_0001", "file:raw_data/groups/dyn_0001/meta.json") in members
    assert ("group:cal_0001", "file:raw_data/groups/cal_0001/servo.parquet") in members

    # a standard reader takes it back: every entity and activity we wrote, under its identifier
    doc = ProvDocument.deserialize(out, format="json")
    ids = {str(r.identifier) for r in doc.get_records() if r.identifier is not None}
    assert set(d["entity"]) | set(d["activity"]) <= ids


def test_held_out():
    assert held_out("validation", "dynamics") and held_out("sealed", "dynamics")
    assert not held_out("train", "dynamics")
    assert held_out("delay_sweep", "delay_sweep") and held_out("deployment", "deployment")
    assert not held_out("attachment", "attachment")
