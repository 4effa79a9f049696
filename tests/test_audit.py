"""esnap audit on hand-built record trees: groups and sets fed, not fed, stale, missing, speed."""

import os

from embodied_snap.lineage import records as pv
from embodied_snap.lineage.audit import audit, compact_ids, format_audit

from lineage_tree import group_files as _group
from lineage_tree import write as _write

INDEX_HEAD = "group_id,evidence_set,category,session\n"


def _tree(root):
    """raw groups -> resample_shard -> windows(train) -> dynamics_train (3 levels); the model also
    lists the separation proof (a gate that read every group through the raw manifest)."""
    groups = {"dyn_0001": ("dynamics", "free_space"), "dyn_0002": ("dynamics", "target"),
              "dyn_0003": ("dynamics", "pilot"), "dyn_0004": ("dynamics", "sealed"),
              "dly_0001": ("delay_sweep", "sweep"), "cal_0001": ("servo_calibration", "burst"),
              "cal_0002": ("servo_calibration", "burst")}
    _write(root, "raw_data/index.csv", (INDEX_HEAD + "".join(
        f"{g},{es},{c},s01\n" for g, (es, c) in groups.items())).encode())
    files = {g: _group(root, g) for g in groups}
    _write(root, "embodied_snap/plan.py", b"# plan")
    man = _write(root, "results/raw/manifest.json", b"{}")
    pv.write_record("raw_manifest", {}, [f for fs in files.values() for f in fs], [man], {}, "t", root=root)
    rs = _write(root, "results/data/50hz/dynamics_train-00.parquet", b"rs")
    pv.write_record("resample_shard", {"shard": "dynamics_train-00"},
                    files["dyn_0001"] + files["dyn_0002"] + files["dyn_0003"] + ["embodied_snap/plan.py"],
                    [rs], {"hz": 50}, "t", root=root)
    w = _write(root, "results/splits/windows_train.npz", b"w")
    pv.write_record("windows", {"role": "train"}, [rs], [w], {}, "t", root=root)
    sep = _write(root, "results/lineage/separation.json", b"{}")
    pv.write_record("check_separation", {}, [man, w], [sep], {}, "t", root=root)
    m = _write(root, "results/dynamics/model.pt", b"m")
    pv.write_record("dynamics_train", {}, [w, sep], [m], {}, "t", root=root)
    return m


def test_audit_chain_groups_and_sets(tmp_path):
    m = _tree(tmp_path)
    r = audit(m, root=tmp_path)
    assert r["record"] == "results/provenance/dynamics_train/_.json"
    assert [j["label"] for j in r["jobs"]] == [
        "dynamics_train", "windows(role=train)", "check_separation", "resample_shard(shard=dynamics_train-00)"]
    assert r["jobs"][2]["gate"]
    dyn = r["evidence_sets"]["dynamics"]
    assert (dyn["n_fed"], dyn["n_total"]) == (3, 4)
    assert list(dyn["fed"]) == ["dyn_0001", "dyn_0002", "dyn_0003"] and dyn["not_fed"] == ["dyn_0004"]
    assert dyn["fed"]["dyn_0002"]["files"]["mocap.parquet"] == pv.sha256(
        tmp_path / "raw_data/groups/dyn_0002/mocap.parquet")
    # the separation proof read every group, but is a gate: those groups did not feed the model
    assert r["not_fed"] == ["delay_sweep", "servo_calibration"]
    assert r["n_groups_fed"] == 3 and not r["stale"] and not r["missing_records"]
    text = format_audit(r)
    assert "stale: no" in text and "dyn_0001-0003" in text
    assert "did not feed it: delay_sweep (0/1), servo_calibration (0/2)" in text
    assert "not fed: dyn_0004" in text
    # an absolute path or a directory of results work too
    assert audit(str(tmp_path / m), root=tmp_path)["n_groups_fed"] == 3
    assert audit("results/dynamics", root=tmp_path)["n_groups_fed"] == 3
    # the manifest itself was fed by every recording
    assert audit("results/raw/manifest.json", root=tmp_path)["n_groups_fed"] == 7


def test_audit_stale_after_raw_change(tmp_path):
    m = _tree(tmp_path)
    raw = tmp_path / "raw_data/groups/dyn_0002/mocap.parquet"
    st = raw.stat()
    os.utime(raw, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # touched, same bytes: not stale
    assert not audit(m, root=tmp_path)["stale"]
    raw.write_bytes(b"changed recording")
    r = audit(m, root=tmp_path)
    assert r["stale"]
    assert [x["path"] for x in r["stale_files"]] == ["raw_data/groups/dyn_0002/mocap.parquet"]
    assert "stale: YES" in format_audit(r) and "dyn_0002/mocap.parquet: sha256 changed" in format_audit(r)
    # a file unrelated to the model changes: the model is not stale
    raw.write_bytes(b"dyn_0002/mocap.parquet")
    (tmp_path / "raw_data/groups/dly_0001/meta.json").write_bytes(b"other")
    assert not audit(m, root=tmp_path)["stale"]


def test_audit_missing_record(tmp_path):
    m = _tree(tmp_path)
    (tmp_path / "results/provenance/resample_shard/shard=dynamics_train-00.json").unlink()
    r = audit(m, root=tmp_path)
    assert r["missing_records"] == ["results/data/50hz/dynamics_train-00.parquet"] and r["stale"]
    assert r["n_groups_fed"] == 0
    assert audit("results/nothing.pdf", root=tmp_path)["missing_records"] == ["results/nothing.pdf"]


def test_compact_ids():
    assert compact_ids(["dyn_0003", "dyn_0001", "dyn_0002", "dyn_0007", "cal_0001", "x"]) == \
        "cal_0001, dyn_0001-0003, dyn_0007, x"


def test_audit_of_a_paper_sized_tree(tmp_path):
    """~1,200 groups / 3,600 raw files through 50 shard jobs, windows and a model (its speed is
    measured by bench/workflow_speed.py, not here)."""
    n, size = 1200, 24
    rows, shard_files = [], {}
    for i in range(n):
        g = f"dyn_{i + 1:04d}"
        rows.append(f"{g},dynamics,free_space,s01\n")
        shard_files.setdefault(i // size, []).extend(_group(tmp_path, g))
    _write(tmp_path, "raw_data/index.csv", (INDEX_HEAD + "".join(rows)).encode())
    outs = []
    for k, fs in shard_files.items():
        o = _write(tmp_path, f"results/data/50hz/dynamics_train-{k:02d}.parquet", b"o")
        pv.write_record("resample_shard", {"shard": f"dynamics_train-{k:02d}"}, fs, [o], {}, "t", root=tmp_path)
        outs.append(o)
    w = _write(tmp_path, "results/splits/windows_train.npz", b"w")
    pv.write_record("windows", {"role": "train"}, outs, [w], {}, "t", root=tmp_path)
    m = _write(tmp_path, "results/dynamics/model.pt", b"m")
    pv.write_record("dynamics_train", {}, [w], [m], {}, "t", root=tmp_path)
    r = audit(m, root=tmp_path)
    assert r["n_groups_fed"] == n and not r["stale"]


def test_groups_given_but_not_read(tmp_path):
    """A job that was given three groups and opened the files of one: one fed, two listed apart."""
    _write(tmp_path, "raw_data/index.csv", (INDEX_HEAD + "".join(
        f"att_000{k},attachment,target,s01\n" for k in (1, 2, 3))).encode())
    files = {g: _group(tmp_path, g) for g in ("att_0001", "att_0002", "att_0003")}
    out = _write(tmp_path, "results/characterize/attachment.json", b"{}")
    pv.write_record("characterize_attachment", {}, [f for fs in files.values() for f in fs], [out], {}, "t",
                    root=tmp_path, reads=files["att_0002"])
    r = audit(out, root=tmp_path)
    assert list(r["evidence_sets"]["attachment"]["fed"]) == ["att_0002"]
    assert r["given_unread"] == ["att_0001", "att_0003"]
    assert "given but never read: att_0001, att_0003" in format_audit(r)
