"""Every kind of tests/gate_corpus.py through `esnap validate` and the workflow's gate, on a copy of
the session's finished smoke run of the simulated rig (conftest.smoke_run).

For each kind, in both modes (the tree read as a real rig's, `raw_data={source: rig}`, and as
the simulated rig's own): a broken one is rejected by `esnap validate` and by the gate exactly as
the workflow calls it before its DAG (verdicts.workflow_gate, in process) with the same single line
(file, group, rule); a benign one passes both. Neither opens the target of a link out of the raw
directory. A handful of kinds (WIRED: an index, a recording, a link out, the one-recording rule, the
sealed set, a benign one) also go through Snakemake itself, proving the wiring is that same gate:
the workflow stops before any job with the identical line, no traceback, and every file under
results/ keeps its sha256. The raw tree is restored after each kind.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
from pathlib import Path

import pandas as pd
import pytest
from gate_corpus import BENIGN, CORPUS, TWIN, opened_any, opens, outside_targets

from test_workflow import run as workflow_run

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
MODES = {"rig": RIG, "twin": ["--config", "budget=smoke"]}
# Imported by the workflow's Python when on its PYTHONPATH: records every file it opens that lies
# at or under one of the targets (a line "watching": the hook was installed).
WATCH = """import os, sys
_log, _of = os.environ["ESNAP_OPENS_LOG"], os.environ["ESNAP_OPENS_OF"].split(os.pathsep)
open(_log, "a").write("watching\\n")
def _hook(event, args):
    if event == "open" and isinstance(args[0], (str, bytes, os.PathLike)):
        real = os.fsdecode(os.path.realpath(args[0]))
        if any(real == t or real.startswith(t + os.sep) for t in _of):
            open(_log, "a").write(real + "\\n")
sys.addaudithook(_hook)
"""

pytestmark = pytest.mark.slow


def run(cmd, cwd, **env):
    return workflow_run(cmd, cwd, check=False, **env)


def snakemake(cwd, *args):
    return run(["snakemake", "--cores", "2", *args], cwd)


def watched_snakemake(cwd, tmp_path, targets, *args):
    """snakemake, and the files among `targets` (real paths) that its process opened."""
    if not targets:
        return snakemake(cwd, *args), []
    (tmp_path / "watch").mkdir()
    (tmp_path / "watch" / "sitecustomize.py").write_text(WATCH)
    log = tmp_path / "opened.txt"
    r = run(
        ["snakemake", "--cores", "2", *args],
        cwd,
        PYTHONPATH=f"{tmp_path / 'watch'}{os.pathsep}{cwd}",
        ESNAP_OPENS_LOG=str(log),
        ESNAP_OPENS_OF=os.pathsep.join(targets),
    )
    lines = log.read_text().split("\n")
    assert "watching" in lines  # the hook was installed
    return r, [p for p in lines if p and p != "watching"]


def digest(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def error_lines(text: str) -> list[str]:
    return [l.strip() for l in text.splitlines() if l.strip().startswith("error:")]


@pytest.fixture(scope="module")
def wf(smoke_run):
    """This module's copy of the session's smoke run (code, recordings, results, Snakemake's records)."""
    d = smoke_run
    shutil.copytree(d / "raw_data", d.parent / "pristine_raw", symlinks=True)
    assert "Nothing to be done" in snakemake(d, "-n", "all", "--config", "budget=smoke").stdout
    return d


@pytest.fixture
def raw(wf):
    """Restore the raw tree after each kind (copy2 keeps times: nothing looks changed)."""
    yield wf / "raw_data"
    shutil.rmtree(wf / "raw_data")
    for p in wf.glob("outside_*"):  # where the corpus puts what it links to
        shutil.rmtree(p)
    shutil.copytree(wf.parent / "pristine_raw", wf / "raw_data", symlinks=True)


def esnap_validate(wf, capsys, monkeypatch, source="rig") -> tuple[int, str, str]:
    """`esnap validate raw_data --source S --config budget=smoke`, in-process (the CLI's entry point)."""
    from embodied_snap.cli import main

    monkeypatch.chdir(wf)
    rc = main(["validate", "raw_data", "--source", source, "--config", "budget=smoke"])
    out = capsys.readouterr()
    return rc, out.out, out.err


def workflow_gate(wf, monkeypatch, args) -> str | None:
    """The error line of the gate the Snakefile runs before its DAG (rules/common.smk), in process,
    with the config that `snakemake ... args` builds; None when it passes."""
    from embodied_snap import runconfig
    from embodied_snap.plan import PlanError
    from embodied_snap.validate import RecordingError
    from embodied_snap.verdicts import workflow_gate

    monkeypatch.chdir(wf)
    try:
        workflow_gate(runconfig.load(entries=args[args.index("--config") + 1:]))
    except (PlanError, RecordingError) as e:
        return f"error: {e}"
    return None


# Through Snakemake as well: an index rule, a recording rule, a link out of the raw directory, the
# rule across groups (and the simulated rig's own answer to it), the sealed set, a benign kind.
WIRED = ["index.csv not text", "tip jumps 2 m for one frame", "meta.json linked to /etc/passwd",
         "same take imported twice", "sealed group re-recorded", "servo.parquet linked inside the raw directory"]


def test_corpus_size():
    assert len(CORPUS) - len(BENIGN) >= 40 and len(BENIGN) >= 5
    assert set(TWIN) <= set(CORPUS) and set(WIRED) <= set(CORPUS)


@pytest.mark.parametrize("kind", list(CORPUS))
def test_kind(wf, raw, kind, capsys, monkeypatch, tmp_path):
    breaks, rig_answer = CORPUS[kind]
    before = digest(wf / "results") if kind in WIRED else None
    breaks(raw)
    targets = outside_targets(raw)  # what a link out of raw_data points at: never to be opened
    for source, args in MODES.items():
        want = TWIN.get(kind, rig_answer) if source == "twin" else rig_answer
        with opens() as seen:
            rc, out, err = esnap_validate(wf, capsys, monkeypatch, source)
            gate_line = workflow_gate(wf, monkeypatch, args)
        assert not opened_any(seen, targets), (source, opened_any(seen, targets))
        if want is None:
            assert rc == 0 and not err and gate_line is None, (source, err, gate_line)
            if kind in WIRED:
                r = snakemake(wf, "-n", "all", *args)  # accepted: the DAG builds (the rebuild is the user's)
                assert r.returncode == 0 and not error_lines(r.stdout + r.stderr), (source, r.stderr[-3000:])
            continue
        # esnap validate: exactly one line, naming the file, the group and the rule
        assert rc == 1 and not out and err.count("\n") == 1, (source, err)
        line = err.strip()
        file, gid, rule = want
        path = (
            f"raw_data/{file}"
            if file in ("index.csv", "sealed.json")
            else f"raw_data/groups/{gid}/{file}".rstrip("/")
        )
        assert line.startswith(f"error: {path}: group {gid}: ") and f"(rule: {rule}" in line, (source, line)
        # the workflow's gate: the identical line
        assert gate_line == line, (source, gate_line)
        if kind not in WIRED:
            continue
        # the workflow itself: stops while the plan is read, with the identical line, and touches nothing
        (tmp_path / source).mkdir()
        r, opened = watched_snakemake(wf, tmp_path / source, targets, "all", *args)
        assert r.returncode != 0, source
        assert error_lines(r.stdout + r.stderr) == [line], (source, (r.stdout + r.stderr)[-3000:])
        assert "Traceback (most recent call last)" not in r.stderr, source
        assert not opened, (source, opened)
        assert digest(wf / "results") == before, source


def test_reseal_is_explicit(wf, raw, capsys, monkeypatch):
    """A deliberate change of the sealed set: refused until `esnap seal` records the new one."""
    CORPUS["sealed group relabelled free_space"][0](raw)
    assert esnap_validate(wf, capsys, monkeypatch)[0] == 1
    from embodied_snap.cli import main

    assert main(["seal", "raw_data", "--config", "budget=smoke", "--source", "rig"]) == 0
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
    assert main(["validate", "raw_data", "--config", "budget=smoke", "--exclude", "att_0004"]) == 0
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
    # a number of that fit is fed by exactly the 7 trials it used, of the set's 8 (issue 28)
    rep = json.loads(run([str(BIN / "esnap"), "audit", "attachment_n", "--json"], wf).stdout)
    s = rep["lineage"]["evidence_sets"]
    assert list(s) == ["attachment"] and s["attachment"]["n_total"] == 8 and not rep["stale"]
    assert s["attachment"]["used"] == [f"att_{i:04d}" for i in (1, 2, 3, 5, 6, 7, 8)]
    ledger = pd.read_csv(wf / "results/tables/claims.csv").set_index("claim_id")
    assert ledger.loc["attachment_n", "fed_by"] == "attachment 7/8"
