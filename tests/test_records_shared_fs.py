"""Provenance records on a cluster's shared file system: many jobs on several nodes write at once,
and audit reads records that name different hosts (the separation proof: tests/test_separation.py)."""

import json
import multiprocessing as mp
import socket

from embodied_snap.lineage import records as pv
from embodied_snap.lineage.audit import audit, format_audit

from lineage_tree import write as _write

N_WRITERS, N_WRITES = 6, 15


def _writer(args):
    root, k = args
    for i in range(N_WRITES):
        # every writer rewrites the same record (a rerun racing a stale job) and one of its own;
        # params differ in size, so a half-written file would not parse
        pv.write_record("shared", {}, ["results/in.txt"], ["results/out.txt"], {"k": k, "pad": "x" * (k * 997 + i)},
                        "t", root=root)
        pv.write_record("own", {"k": str(k)}, ["results/in.txt"], [f"results/own{k}.txt"], {"i": i}, "t", root=root)
    return k


def test_concurrent_writers_never_leave_half_a_record(tmp_path):
    _write(tmp_path, "results/in.txt", b"in")
    _write(tmp_path, "results/out.txt", b"out")
    for k in range(N_WRITERS):
        _write(tmp_path, f"results/own{k}.txt", str(k).encode())
    shared = pv.record_path("shared", {}, tmp_path)
    errors, reads = [], 0
    with mp.get_context("spawn").Pool(N_WRITERS) as pool:
        res = pool.map_async(_writer, [(str(tmp_path), k) for k in range(N_WRITERS)])
        while not res.ready():  # read while they write: every read parses
            pv.load_records(tmp_path, errors)
            if shared.exists():
                json.loads(shared.read_text())
                reads += 1
        assert sorted(res.get()) == list(range(N_WRITERS))
    assert not errors and reads > 0
    recs = pv.load_records(tmp_path, errors)
    assert not errors
    assert {r["_record"] for r in recs.values()} == {
        "results/provenance/shared/_.json", *(f"results/provenance/own/k={k}.json" for k in range(N_WRITERS))}
    # no temporary file is left behind
    assert sorted(p.name for p in (tmp_path / pv.RECORDS_DIR / "shared").iterdir()) == ["_.json"]


def _tree_on_hosts(root):
    """raw group -> resample (node-a) -> windows (node-b) -> model (this host)."""
    raw = [_write(root, f"raw_data/groups/dyn_0001/{f}", f.encode()) for f in ("mocap.parquet", "meta.json")]
    _write(root, "raw_data/index.csv", b"group_id,evidence_set,category,session\ndyn_0001,dynamics,free_space,s01\n")
    rs = _write(root, "results/data/50hz/dynamics_train-00.parquet", b"rs")
    a = pv.write_record("resample_shard", {"shard": "dynamics_train-00"}, raw, [rs], {}, "t", root=root)
    w = _write(root, "results/splits/windows_train.npz", b"w")
    b = pv.write_record("windows", {"role": "train"}, [rs], [w], {}, "t", root=root)
    m = _write(root, "results/dynamics/model.pt", b"m")
    pv.write_record("dynamics_train", {"seed": "0"}, [w], [m], {}, "t", root=root)
    for path, host in ((a, "node-a"), (b, "node-b")):
        rec = json.loads(path.read_text())
        rec["host"] = host
        path.write_text(json.dumps(rec))
    return m


def test_audit_reads_records_from_several_hosts(tmp_path):
    m = _tree_on_hosts(tmp_path)
    r = audit(m, root=tmp_path)
    assert r["hosts"] == sorted({"node-a", "node-b", socket.gethostname()})
    assert r["n_groups_fed"] == 1 and not r["stale"]
    assert "jobs ran on 3 hosts" in format_audit(r)
