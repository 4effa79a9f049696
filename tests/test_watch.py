"""Nothing escapes the watch: a job's reads are seen from its interpreter's start (the start-up hook
the workflow puts on its jobs' PYTHONPATH), so a read of a sealed file inside `tracked()`, at the
script's top level, before its first statement or in a package module's import fails the job with
the same one line, a job forced past that check is caught by check-separation, and a job whose
interpreter did not start the watch fails."""

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
# The tests reading `runs` run Snakemake on a small workflow: make test, not make test-fast.
slow = pytest.mark.slow
SEALED = "results/splits/windows_sealed.npz"
CASES = ("inside", "top", "import", "first")

# One job per case (wildcard `case`), reading the train windows it declares and, depending on the
# case, the sealed windows it does not. `force` bypasses the job's own check (a job forced through).
SCRIPT = f'''"""A job that reads {SEALED} without declaring it."""

if snakemake.wildcards.case == "first":
    open("{SEALED}", "rb").close()  # before any import, the bookkeeping's too

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

# A package module loaded before the bookkeeping: watched from the start, that is no matter.
EARLY = '''"""A job whose script loads a package module before the bookkeeping."""

import sys

import embodied_snap.quiet  # noqa: F401
from embodied_snap.lineage.records import tracked

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    open(snakemake.output[0], "w").write("x")
'''

# The workflow's job environment as rules/common.smk sets it; `unhooked` leaves it out.
SNAKEFILE = """
import os
from embodied_snap.lineage.records import job_environment

if not config.get("unhooked"):
    os.environ.update(job_environment())

rule all:
    input: expand("results/dynamics/model_{case}.pt", case=["clean", "inside", "top", "import", "first"])

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
    for f in ("__init__.py", "lineage/__init__.py", "lineage/records.py", "lineage/startup/sitecustomize.py"):
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
    """The workflow run three times: as it is (each leaking job fails), with the jobs forced through,
    and one job without the start-up hook."""
    root = _workflow(tmp_path_factory.mktemp("watch"))
    plain = _snakemake(root, "all", "results/early.txt")
    logs = {p.stem: p.read_text() for p in (root / "logs").glob("*.log")}
    recorded = {c: pv.record_path("dynamics_train", {"case": c}, root).exists() for c in ("clean", *CASES)}
    recorded["early"] = pv.record_path("early", {}, root).exists()
    forced = _snakemake(root, "all", "--config", "force=1")
    unhooked = _snakemake(root, "results/early.txt", "--forcerun", "early", "--config", "unhooked=1")
    logs["unhooked"] = (root / "logs/early.log").read_text()
    return root, plain, logs, recorded, forced, unhooked


@slow
@pytest.mark.parametrize("case", CASES)
def test_a_sealed_read_fails_its_job_with_one_line(runs, case):
    """Inside tracked(), at the script's top level, in a package module's import, before the script's
    first statement: the same line."""
    _, plain, logs, recorded, _, _ = runs
    assert plain.returncode != 0
    assert logs[case].strip() == (f"error: {SEALED}: read by rule dynamics_train but not among its declared "
                                  "inputs (rule: a job reads only what it declares)")
    assert not recorded[case]


@slow
def test_the_clean_job_passes_and_its_reads_are_recorded(runs):
    """A job reading only what it declares passes (Snakemake's preamble loaded no package module before
    the watch) and its record lists what it read."""
    root, _, logs, recorded, _, _ = runs
    assert logs["clean"] == "" and recorded["clean"]
    rec = json.loads(pv.record_path("dynamics_train", {"case": "clean"}, root).read_text())
    assert rec["reads"] == ["results/splits/windows_train.npz"]


@slow
def test_a_module_loaded_before_the_bookkeeping_is_watched_all_the_same(runs):
    _, _, logs, recorded, _, _ = runs
    assert logs["early"] == "" and recorded["early"]


@slow
def test_a_job_not_watched_from_its_start_fails(runs):
    """Without the start-up hook (a job environment other than the workflow's) a job fails in one line."""
    _, _, logs, _, _, unhooked = runs
    assert unhooked.returncode != 0
    assert logs["unhooked"].strip() == (
        "error: workflow_scripts/early.py: run by rule early without the watch from its start (rule: a job's "
        "reads are watched from its interpreter's start by embodied_snap/lineage/startup/sitecustomize.py, "
        "which the workflow puts on its jobs' PYTHONPATH, docs/lineage.md)")


@slow
@pytest.mark.parametrize("case", CASES)
def test_check_separation_fails_when_the_job_is_forced_through(runs, case):
    root, _, _, _, forced, _ = runs
    assert forced.returncode == 0, forced.stderr[-3000:]
    r = subprocess.run([str(Path(sys.executable).parent / "esnap"), "check-separation", "--no-static"], cwd=root,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, r.stdout + r.stderr
    out = f"separation (records): results/dynamics/model_{case}.pt (rule dynamics_train"
    lines = [ln for ln in (r.stdout + r.stderr).splitlines() if out in ln]
    assert any(f"was fed by sealed group dyn_0004 through {SEALED}" in ln for ln in lines), lines
    assert any(f"read {SEALED}, not among its declared inputs" in ln for ln in lines), lines


def _python(tmp_path, script_dir: str, *paths) -> str:
    """What a script run from `script_dir` (under tmp_path) says, with `paths` on PYTHONPATH."""
    d = tmp_path / script_dir
    d.mkdir(parents=True, exist_ok=True)
    (d / "tmp1a2b.job.py").write_text("import sys\nr = sys.modules.get('embodied_snap.lineage.records')\n"
                                      "print(bool(r and r._from_start), bool(r and r._opened is not None))\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(map(str, (*paths, REPO)))}
    r = subprocess.run([sys.executable, str(d / "tmp1a2b.job.py")], cwd=tmp_path, env=env, capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_the_start_up_hook_watches_snakemakes_scripts_only(tmp_path):
    """Snakemake's copy of a script is watched from its start; any other Python is not (nor does it load
    the bookkeeping), and a sitecustomize further down the path still runs."""
    assert _python(tmp_path, ".snakemake/scripts", pv.STARTUP) == "True True\n"
    assert _python(tmp_path, "elsewhere/scripts", pv.STARTUP) == "False False\n"
    assert _python(tmp_path, ".snakemake/scripts") == "False False\n"  # no hook: nothing
    (tmp_path / "next").mkdir()
    (tmp_path / "next/sitecustomize.py").write_text("print('next hook')\n")
    assert _python(tmp_path, ".snakemake/scripts", pv.STARTUP, tmp_path / "next") == "next hook\nTrue True\n"
    assert _python(tmp_path, "other", pv.STARTUP, tmp_path / "next") == "next hook\nFalse False\n"


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
    # the start-up hook: standard library, and in a job records (and the two code-free packages above it)
    mods, rel = imported(pv.STARTUP / "sitecustomize.py")
    assert mods - set(sys.stdlib_module_names) == {"embodied_snap"} and not rel
    assert "from embodied_snap.lineage import records" in (pv.STARTUP / "sitecustomize.py").read_text()
    assert pv.__name__ in EXEMPT & pv.EXEMPT_MODULES
