"""What a job really touched: every reader's files are seen, undeclared reads and modules fail the
job with one line, and parquet is read only through embodied_snap.io (pyarrow's own C++ reads
are invisible to Python's audit hook)."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
import torch
from snakemake.iocontainers import Namedlist

from embodied_snap import io
from embodied_snap.lineage import records as pv

REPO = Path(__file__).resolve().parent.parent


def _smk(inputs, outputs=("results/out.json",), rule="step", raw="raw_data"):
    return SimpleNamespace(rule=rule, input=Namedlist(list(inputs)), output=Namedlist(list(outputs)),
                           wildcards=Namedlist(fromdict={}), params=Namedlist(fromdict={}),
                           log=Namedlist([]), config={"raw_data": {"dir": raw}})


def _files(root):
    (root / "results").mkdir()
    (root / "raw_data/groups/g1").mkdir(parents=True)
    (root / "results/a.json").write_text("{}")
    np.save(root / "results/b.npy", np.arange(3))
    torch.save({"w": torch.zeros(2)}, root / "results/c.pt")
    pd.DataFrame({"x": [1.0]}).to_parquet(root / "raw_data/groups/g1/mocap.parquet")
    pd.DataFrame({"x": [1.0]}).to_csv(root / "results/d.csv", index=False)
    return ["results/a.json", "results/b.npy", "results/c.pt", "raw_data/groups/g1/mocap.parquet", "results/d.csv"]


def _read_all(root):
    json.load(open(root / "results/a.json"))
    np.load(root / "results/b.npy")
    torch.load(root / "results/c.pt", weights_only=True)
    io.read_parquet(root / "raw_data/groups/g1/mocap.parquet")
    pd.read_csv(root / "results/d.csv")


def test_every_reader_is_recorded(tmp_path):
    declared = _files(tmp_path)
    with pv.tracked(_smk(declared), root=tmp_path, check_modules=False):
        _read_all(tmp_path)
        (tmp_path / "results/out.json").write_text("{}")
    rec = json.loads((tmp_path / "results/provenance/step/_.json").read_text())
    assert rec["reads"] == sorted(declared)
    assert rec["raw_dir"] == "raw_data" and rec["config_sha256"]


@pytest.mark.parametrize("undeclared", ["results/b.npy", "results/c.pt", "raw_data/groups/g1/mocap.parquet",
                                        "results/a.json", "results/d.csv"])
def test_an_undeclared_read_fails_the_job_with_one_line(tmp_path, undeclared):
    declared = [f for f in _files(tmp_path) if f != undeclared]
    with pytest.raises(SystemExit) as e:
        with pv.tracked(_smk(declared), root=tmp_path, check_modules=False):
            _read_all(tmp_path)
    assert str(e.value) == (f"error: {undeclared}: read by rule step but not among its declared inputs "
                            "(rule: a job reads only what it declares)")
    assert not (tmp_path / "results/provenance/step/_.json").exists()


def test_reads_outside_results_and_raw_are_recorded_not_checked(tmp_path):
    (tmp_path / "reference").mkdir()
    (tmp_path / "reference/v.yaml").write_text("a: 1")
    with pv.tracked(_smk([]), root=tmp_path, check_modules=False):
        open(tmp_path / "reference/v.yaml").read()
        (tmp_path / "results").mkdir()
        (tmp_path / "results/out.json").write_text("{}")
    assert json.loads((tmp_path / "results/provenance/step/_.json").read_text())["reads"] == ["reference/v.yaml"]


def test_the_raw_directory_comes_from_config(tmp_path):
    (tmp_path / "lab/groups/g1").mkdir(parents=True)
    (tmp_path / "lab/groups/g1/meta.json").write_text("{}")
    with pytest.raises(SystemExit, match="lab/groups/g1/meta.json: read by rule step"):
        with pv.tracked(_smk([], raw="lab"), root=tmp_path, check_modules=False):
            open(tmp_path / "lab/groups/g1/meta.json").read()


def test_an_undeclared_module_fails_the_job(tmp_path):
    """In a fresh interpreter, as a job runs: loading a package module that is not a code input."""
    (tmp_path / "embodied_snap").mkdir()
    (tmp_path / "embodied_snap/quat.py").write_text("# declared")
    prog = (
        "import sys\nfrom types import SimpleNamespace\nfrom snakemake.iocontainers import Namedlist\n"
        "from embodied_snap.lineage.records import tracked\n"
        "smk = SimpleNamespace(rule='step', input=Namedlist(['embodied_snap/quat.py']), output=Namedlist([]),"
        " wildcards=Namedlist(fromdict={}), params=Namedlist(fromdict={}), log=Namedlist([]), config={})\n"
        "with tracked(smk, root=sys.argv[1]):\n"
        "    import embodied_snap.quat\n"
        "    if sys.argv[2] == 'more':\n"
        "        import embodied_snap.bearing\n")
    ok = subprocess.run([sys.executable, "-c", prog, str(tmp_path), "declared"], cwd=REPO, capture_output=True,
                        text=True)
    assert ok.returncode == 0, ok.stderr
    bad = subprocess.run([sys.executable, "-c", prog, str(tmp_path), "more"], cwd=REPO, capture_output=True,
                         text=True)
    assert bad.returncode == 1
    assert bad.stderr.strip() == ("error: embodied_snap/bearing.py: loaded by rule step but not among its code "
                                  "inputs (rule: code inputs are the script's imports, lineage/imports.py)")


def test_parquet_is_read_only_through_io():
    """pyarrow/pandas parquet readers are called nowhere but embodied_snap/io.py."""
    readers = {"read_parquet", "read_table", "read_metadata", "ParquetFile", "ParquetDataset", "read_schema"}
    hits = []
    for f in sorted([*(REPO / "embodied_snap").rglob("*.py"), *(REPO / "workflow_scripts").glob("*.py")]):
        if f == REPO / "embodied_snap/io.py":
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Attribute) and node.attr in readers:
                owner = node.value.id if isinstance(node.value, ast.Name) else ""
                if owner in ("pd", "pq", "pandas", "pyarrow", "parquet"):
                    hits.append(f"{f.relative_to(REPO)}:{node.lineno} {owner}.{node.attr}")
    assert hits == []
