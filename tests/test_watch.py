"""Nothing escapes the watch: a job's reads are seen from its script's first statement, so a read of
a sealed file inside `tracked()`, at the script's top level or in a package module's import fails
the job with the same one line, and a job forced past that check is caught by check-separation."""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from test_separation import _run

from embodied_snap.lineage import records as pv

REPO = Path(__file__).resolve().parent.parent
SEALED = "results/splits/windows_sealed.npz"
CASES = ("inside", "top", "import")

# One job per case (wildcard `case`), reading the train windows it declares and, depending on the
# case, the sealed windows it does not. `force` bypasses the job's own check (a job forced through).
SCRIPT = f'''"""A job that reads {SEALED} without declaring it."""

from embodied_snap.lineage import records  # noqa: F401

# isort: split

import sys

import numpy as np

case = snakemake.wildcards.case
if case == "import":
    import embodied_snap.leaky  # noqa: F401 -- reads the sealed windows at import

from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
if snakemake.config.get("force"):
    records.check_declared = lambda *a: None
if case == "top":
    np.load("{SEALED}")
with tracked(snakemake):
    if case == "inside":
        np.load("{SEALED}")
    np.load(snakemake.input[0])
    open(snakemake.output[0], "w").write(case)
'''

# A package module loaded before the watch began: its import-time reads were not seen.
EARLY = '''"""A job whose script loads a package module before the watch."""

import sys

import embodied_snap.quiet  # noqa: F401
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    open(snakemake.output[0], "w").write("x")
'''

SNAKEFILE = """
rule all:
    input: expand("results/dynamics/model_{case}.pt", case=["clean", "inside", "top", "import"])

rule dynamics_train:
    input: "results/splits/windows_train.npz", "embodied_snap/leaky.py"
    output: "results/dynamics/model_{case}.pt"
    log: "logs/{case}.log"
    script: "workflow_scripts/leak.py"

rule early:
    input: "embodied_snap/quiet.py"
    output: "results/early.txt"
    log: "logs/early.log"
    script: "workflow_scripts/early.py"
"""


def _workflow(root: Path) -> Path:
    """A finished run's records (test_separation) plus a tiny workflow whose package is a copy of the
    bookkeeping and two modules of its own."""
    _run(root)
    for f in ("__init__.py", "lineage/__init__.py", "lineage/records.py"):
        (root / "embodied_snap" / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / "embodied_snap" / f, root / "embodied_snap" / f)
    (root / "embodied_snap/leaky.py").write_text(f'import numpy as np\n\nnp.load("{SEALED}")\n')
    (root / "embodied_snap/quiet.py").write_text("")
    (root / "workflow_scripts").mkdir()
    (root / "workflow_scripts/leak.py").write_text(SCRIPT)
    (root / "workflow_scripts/early.py").write_text(EARLY)
    (root / "Snakefile").write_text(SNAKEFILE)
    return root


def _snakemake(root: Path, *args: str) -> subprocess.CompletedProcess:
    # the jobs import the workflow's own copy of the package, not the repository's
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run([sys.executable, "-m", "snakemake", "--cores", "1", "--keep-going", *args], cwd=root,
                          env=env, capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The workflow run twice: as it is (each leaking job fails), then with the jobs forced through."""
    root = _workflow(tmp_path_factory.mktemp("watch"))
    plain = _snakemake(root, "all", "results/early.txt")
    logs = {p.stem: p.read_text() for p in (root / "logs").glob("*.log")}
    recorded = {c: pv.record_path("dynamics_train", {"case": c}, root).exists() for c in ("clean", *CASES)}
    forced = _snakemake(root, "all", "--config", "force=1")
    return root, plain, logs, recorded, forced


@pytest.mark.parametrize("case", CASES)
def test_a_sealed_read_fails_its_job_with_one_line(runs, case):
    """Inside tracked(), at the script's top level, in a package module's import: the same line."""
    _, plain, logs, recorded, _ = runs
    assert plain.returncode != 0
    assert logs[case].strip() == (f"error: {SEALED}: read by rule dynamics_train but not among its declared "
                                  "inputs (rule: a job reads only what it declares)")
    assert not recorded[case]


def test_the_clean_job_passes_and_its_reads_are_recorded(runs):
    """A job reading only what it declares passes (Snakemake's preamble loaded no package module before
    the watch) and its record lists what it read."""
    root, _, logs, recorded, _ = runs
    assert logs["clean"] == "" and recorded["clean"]
    rec = json.loads(pv.record_path("dynamics_train", {"case": "clean"}, root).read_text())
    assert rec["reads"] == ["results/splits/windows_train.npz"]


def test_a_module_loaded_before_the_watch_fails_the_job(runs):
    _, _, logs, _, _ = runs
    assert logs["early"].strip() == (
        "error: embodied_snap/quiet.py: loaded by rule early before its reads were watched (rule: a workflow "
        "script's first statement is `from embodied_snap.lineage import records`, docs/lineage.md)")


@pytest.mark.parametrize("case", CASES)
def test_check_separation_fails_when_the_job_is_forced_through(runs, case):
    root, _, _, _, forced = runs
    assert forced.returncode == 0, forced.stderr[-3000:]
    r = subprocess.run([str(Path(sys.executable).parent / "esnap"), "check-separation", "--no-static"], cwd=root,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, r.stdout + r.stderr
    out = f"separation (records): results/dynamics/model_{case}.pt (rule dynamics_train"
    lines = [ln for ln in (r.stdout + r.stderr).splitlines() if out in ln]
    assert any(f"was fed by sealed group dyn_0004 through {SEALED}" in ln for ln in lines), lines
    assert any(f"read {SEALED}, not among its declared inputs" in ln for ln in lines), lines


def test_every_workflow_script_starts_with_the_watch():
    """The first statement after the docstring, in every script (a new one joins without an edit)."""
    scripts = sorted((REPO / "workflow_scripts").glob("*.py"))
    assert len(scripts) > 40
    bad = []
    for f in scripts:
        body = ast.parse(f.read_text()).body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            body = body[1:]
        if not body or ast.unparse(body[0]) != pv.WATCH_IMPORT:
            bad.append(f.name)
    assert bad == []


def test_the_watch_is_standard_library_only_and_exempt():
    from embodied_snap.lineage.imports import EXEMPT

    def imported(path):
        mods, rel = set(), set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                mods |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                (rel if node.level else mods).add(node.module.split(".")[0] if node.module else ".")
        return mods, rel

    mods, rel = imported(REPO / "embodied_snap/lineage/records.py")
    assert mods <= set(sys.stdlib_module_names) | {"__future__"}
    # within the package, only the file helpers (one atomic write, one sha256), themselves stdlib only
    assert rel == {"files"}
    mods, rel = imported(REPO / "embodied_snap/files.py")
    assert mods <= set(sys.stdlib_module_names) | {"__future__"} and not rel
    assert "embodied_snap.files" in EXEMPT
    # the watch line loads records (and the two code-free packages above it), never a code input
    assert pv.WATCH_IMPORT == f"from {pv.__name__.rpartition('.')[0]} import records"
    assert pv.__name__ in EXEMPT & pv.EXEMPT_MODULES
