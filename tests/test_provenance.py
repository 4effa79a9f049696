"""Provenance records: content, naming, atomic write, tracked() semantics."""

import hashlib
import json
import sys
from types import SimpleNamespace

import pytest
from snakemake.iocontainers import Namedlist

from embodied_snap.lineage import groups
from embodied_snap.lineage import records as pv


def _write(root, rel, data=b"x"):
    p = root / rel
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_bytes(data)
    return rel


def test_write_record_content(tmp_path):
    a = _write(tmp_path, "raw_data/groups/dyn_0001/mocap.parquet", b"mocap")
    code = _write(tmp_path, "embodied_snap/resample.py", b"# code")
    script = _write(tmp_path, "workflow_scripts/resample.py", b"# script")
    _write(tmp_path, "results/out/dir/a.txt", b"a")
    _write(tmp_path, "results/out/dir/sub/b.txt", b"b")
    out = _write(tmp_path, "results/data/50hz/dynamics_train-00.parquet", b"out")
    p = pv.write_record("resample_shard", {"shard": "dynamics_train-00"}, [a, code, script],
                        [out, "results/out/dir"], {"hz": 50, "obj": object()}, "2026-01-01T00:00:00+00:00",
                        root=tmp_path)
    assert p == tmp_path / "results/provenance/resample_shard/shard=dynamics_train-00.json"
    rec = json.loads(p.read_text())
    assert rec["rule"] == "resample_shard" and rec["wildcards"] == {"shard": "dynamics_train-00"}
    assert [e["path"] for e in rec["inputs"]] == [a]  # code kept apart from data
    assert [e["path"] for e in rec["code"]] == [code, script]
    assert rec["inputs"][0]["sha256"] == hashlib.sha256(b"mocap").hexdigest()
    assert rec["inputs"][0]["bytes"] == 5 and rec["inputs"][0]["mtime_ns"] > 0
    # directories are expanded to their files
    assert [e["path"] for e in rec["outputs"]] == [out, "results/out/dir/a.txt", "results/out/dir/sub/b.txt"]
    assert rec["params"]["hz"] == 50 and isinstance(rec["params"]["obj"], str)
    assert set(rec["packages"]) >= {"snakemake", "numpy", "pandas", "torch", "scikit-learn"}
    assert rec["packages"]["snakemake"] == "9.27.1"
    assert "git_commit" in rec["code_version"] or "package_version" in rec["code_version"]
    assert rec["started"] and rec["finished"] >= rec["started"] and rec["host"]
    # atomic write leaves no temporary files beside the record
    assert [f.name for f in p.parent.iterdir()] == [p.name]


def test_record_names(tmp_path):
    assert pv.record_path("split", {}, tmp_path).name == "_.json"
    assert pv.record_path("x", {"b": "2", "a": "p/q"}, tmp_path).name == "a=p%2Fq,b=2.json"


def _smk(rule, inputs, outputs, wildcards=None, params=None):
    return SimpleNamespace(rule=rule, input=Namedlist(inputs), output=Namedlist(outputs),
                           wildcards=Namedlist(fromdict=wildcards or {}),
                           params=Namedlist(fromdict=params or {}), log=Namedlist([]))


def test_tracked_writes_on_success_and_removes_old_on_failure(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "argv", [str(tmp_path / ".snakemake/scripts/tmpab12cd.windows.py")])
    _write(tmp_path, "workflow_scripts/windows.py", b"# script")
    i = _write(tmp_path, "results/data/50hz/dynamics_train-00.parquet", b"in")
    smk = _smk("windows", [i, "embodied_snap/plan.py"], ["results/splits/windows_train.npz"],
               {"role": "train"}, {"history": 20})
    _write(tmp_path, "embodied_snap/plan.py", b"# plan")
    rp = tmp_path / "results/provenance/windows/role=train.json"
    with pv.tracked(smk, root=tmp_path, check_modules=False):
        assert not rp.exists()
        _write(tmp_path, "results/splits/windows_train.npz", b"npz")
    rec = json.loads(rp.read_text())
    assert rec["wildcards"] == {"role": "train"} and rec["params"] == {"history": 20}
    assert [e["path"] for e in rec["code"]] == ["embodied_snap/plan.py", "workflow_scripts/windows.py"]
    # a failing job deletes the old record and writes none
    with pytest.raises(RuntimeError):
        with pv.tracked(smk, root=tmp_path, check_modules=False):
            raise RuntimeError("boom")
    assert not rp.exists()


def test_load_records_and_groups(tmp_path):
    a = _write(tmp_path, "raw_data/groups/dyn_0001/meta.json", b"{}")
    pv.write_record("resample_shard", {"shard": "s-00"}, [a], [_write(tmp_path, "results/o.parquet")], {},
                    "t", root=tmp_path)
    recs = pv.load_records(tmp_path)
    assert set(recs) == {"results/o.parquet"}
    assert recs["results/o.parquet"]["_record"] == "results/provenance/resample_shard/shard=s-00.json"
    assert groups.group_of("raw_data/groups/dyn_0001/meta.json") == ("dyn_0001", "meta.json")
    assert groups.group_of("results/raw/manifest.json") is None
    _write(tmp_path, "raw_data/index.csv",
           b"group_id,evidence_set,category,session\ndyn_0001,dynamics,sealed,s01\ndyn_0002,dynamics,pilot,s01\n"
           b"dly_0001,delay_sweep,sweep,s02\n")
    g = groups.load_groups(tmp_path)
    assert g["dyn_0001"]["role"] == "sealed" and g["dyn_0002"]["role"] == "dynamics"
    assert g["dly_0001"]["role"] == "delay_sweep"
    _write(tmp_path, "results/splits/split.csv", b"group_id,role\ndyn_0002,validation\n")
    assert groups.load_groups(tmp_path)["dyn_0002"]["role"] == "validation"


@pytest.mark.slow
def test_tracked_inside_snakemake(tmp_path):
    """The helper as workflow scripts use it: through Snakemake's `script:` directive."""
    import subprocess

    _write(tmp_path, "raw_data/groups/g1/meta.json", b"{}")
    _write(tmp_path, "embodied_snap/mod.py", b"# a module the script imports")
    (tmp_path / "workflow_scripts").mkdir()
    (tmp_path / "workflow_scripts/step.py").write_text(
        "from embodied_snap.lineage.records import tracked\n"
        "with tracked(snakemake):\n"
        "    open(snakemake.output[0], 'w').write('out')\n")
    (tmp_path / "Snakefile").write_text(
        'rule all:\n    input: "results/s1.txt"\n'
        'rule step:\n    input: data="raw_data/groups/g1/meta.json", code="embodied_snap/mod.py"\n'
        '    output: "results/{name}.txt"\n    params: k=3\n    script: "workflow_scripts/step.py"\n')
    r = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "1", "-q", "all"], cwd=tmp_path,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rec = json.loads((tmp_path / "results/provenance/step/name=s1.json").read_text())
    assert rec["wildcards"] == {"name": "s1"} and rec["params"] == {"k": 3}
    assert [e["path"] for e in rec["inputs"]] == ["raw_data/groups/g1/meta.json"]
    assert [e["path"] for e in rec["code"]] == ["embodied_snap/mod.py", "workflow_scripts/step.py"]
    assert rec["outputs"][0]["path"] == "results/s1.txt"
