"""Every kind of tests/gate_corpus.py through both `esnap validate` and the workflow, on a copy of
a finished smoke run read as a real rig's tree (`raw_data={source: rig}`).

For each kind: a broken one is rejected by both with the same single line (file, group, rule),
the workflow stops before any job, and every file under results/ keeps its sha256; a benign one
passes both. The raw tree is restored after each kind. One smoke run serves the module.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from gate_corpus import BENIGN, CORPUS

REPO = Path(__file__).resolve().parent.parent
COPY = [
    "Snakefile",
    "config.yaml",
    "rules",
    "workflow_scripts",
    "schemas",
    "envs",
    "profiles",
    "reference",
    "report",
    "embodied_snap",
]
BIN = Path(sys.executable).parent
RIG = ["--config", "budget=smoke", "raw_data={source: rig, dir: raw_data}"]

pytestmark = pytest.mark.slow


def run(cmd, cwd):
    env = {**os.environ, "PYTHONPATH": str(cwd), "PATH": f"{BIN}:{os.environ['PATH']}"}
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)


def snakemake(cwd, *args):
    return run(["snakemake", "--cores", "2", *args], cwd)


def digest(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def error_lines(text: str) -> list[str]:
    return [l.strip() for l in text.splitlines() if l.strip().startswith("error:")]


@pytest.fixture(scope="module")
def wf(tmp_path_factory):
    d = tmp_path_factory.mktemp("corpus")
    for name in COPY:
        src = REPO / name
        if src.is_dir():
            shutil.copytree(src, d / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(src, d / name)
    for args in (["all", "--config", "budget=smoke"], ["all", *RIG]):  # the twin records; read as a rig's
        r = snakemake(d, *args)
        assert r.returncode == 0, r.stderr[-3000:]
    shutil.copytree(d / "raw_data", d.parent / "pristine_raw", symlinks=True)
    assert "Nothing to be done" in snakemake(d, "-n", "all", *RIG).stdout
    return d


@pytest.fixture
def raw(wf):
    """Restore the raw tree after each kind (copy2 keeps times: nothing looks changed)."""
    yield wf / "raw_data"
    shutil.rmtree(wf / "raw_data")
    for p in wf.parent.glob("outside_*"):
        shutil.rmtree(p)
    shutil.copytree(wf.parent / "pristine_raw", wf / "raw_data", symlinks=True)


def esnap_validate(wf, capsys, monkeypatch) -> tuple[int, str, str]:
    """`esnap validate raw_data --budget smoke`, in-process (the same entry point as the CLI)."""
    from embodied_snap.cli import main

    monkeypatch.chdir(wf)
    rc = main(["validate", "raw_data", "--budget", "smoke"])
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_corpus_size():
    assert len(CORPUS) - len(BENIGN) >= 40 and len(BENIGN) >= 5


@pytest.mark.parametrize("kind", list(CORPUS))
def test_kind(wf, raw, kind, capsys, monkeypatch):
    breaks, want = CORPUS[kind]
    before = digest(wf / "results")
    breaks(raw)
    rc, out, err = esnap_validate(wf, capsys, monkeypatch)
    if want is None:
        assert rc == 0 and not err, err
        r = snakemake(wf, "-n", "all", *RIG)  # accepted: the DAG builds (the rebuild is the user's)
        assert r.returncode == 0 and not error_lines(r.stdout + r.stderr), r.stderr[-3000:]
        return
    # esnap validate: exactly one line, naming the file, the group and the rule
    assert rc == 1 and not out and err.count("\n") == 1, err
    line = err.strip()
    file, gid, rule = want
    path = (
        f"raw_data/{file}"
        if file in ("index.csv", "sealed.json")
        else f"raw_data/groups/{gid}/{file}".rstrip("/")
    )
    assert line.startswith(f"error: {path}: group {gid}: ") and f"(rule: {rule}" in line, line
    # the workflow: stops while the plan is read, with the same line, and touches nothing
    r = snakemake(wf, "all", *RIG)
    assert r.returncode != 0
    assert error_lines(r.stdout + r.stderr) == [line], (r.stdout + r.stderr)[-3000:]
    assert "Traceback (most recent call last)" not in r.stderr
    assert digest(wf / "results") == before


def test_reseal_is_explicit(wf, raw, capsys, monkeypatch):
    """A deliberate change of the sealed set: refused until `esnap seal` records the new one."""
    CORPUS["sealed group relabelled free_space"][0](raw)
    assert esnap_validate(wf, capsys, monkeypatch)[0] == 1
    from embodied_snap.cli import main

    assert main(["seal", "raw_data", "--budget", "smoke", "--source", "rig"]) == 0
    out = capsys.readouterr().out
    assert "sealed set: 1 groups: dyn_0008; was: dyn_0007, dyn_0008; recorded in raw_data/sealed.json" in out
    assert esnap_validate(wf, capsys, monkeypatch)[0] == 0
    r = snakemake(wf, "-n", "all", *RIG)
    assert r.returncode == 0 and not error_lines(r.stdout + r.stderr), r.stderr[-3000:]


def test_exclusion_is_the_users_decision(wf, raw, capsys, monkeypatch):
    """Last (it rebuilds): a rejected group left out explicitly. Both accept it, the DAG no longer
    reads it, and the audit of the attachment fit names it as excluded, with the reason."""
    CORPUS["target never tracked"][0](raw)
    from embodied_snap.cli import main

    monkeypatch.chdir(wf)
    assert main(["validate", "raw_data", "--budget", "smoke", "--exclude", "att_0004"]) == 0
    assert "excluded: att_0004 (raw_data.exclude)" in capsys.readouterr().out
    cfg = [
        "--config",
        "budget=smoke",
        "raw_data={source: rig, dir: raw_data, exclude: {att_0004: target never tracked}}",
    ]
    r = snakemake(wf, "-n", "all", *cfg)
    assert r.returncode == 0 and "characterize_attachment" in r.stdout, r.stderr[-3000:]
    r = snakemake(wf, "all", *cfg)
    assert r.returncode == 0, r.stderr[-3000:]
    fit = json.loads((wf / "results/characterize/attachment.json").read_text())
    assert fit["n"] == 7
    r = run([str(BIN / "esnap"), "audit", "results/characterize/attachment.json"], wf)
    assert "excluded: att_0004, target never tracked" in r.stdout
    rep = json.loads(
        run([str(BIN / "esnap"), "audit", "results/characterize/attachment.json", "--json"], wf).stdout
    )
    assert "att_0004" not in rep["evidence_sets"]["attachment"]["fed"] and not rep["stale"]
    assert rep["evidence_sets"]["attachment"]["n_fed"] == 7
