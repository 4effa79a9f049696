"""Code inputs are derived from the imports, and every job checks itself against them.

The rules' `code` inputs come from a static import graph (lineage/imports.py). Here the closure is
built independently, by Python's own import machinery: a subprocess runs each script's import
statements and reads `sys.modules`.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest

from embodied_snap.lineage import imports
from embodied_snap.lineage.dag import rule_table

from importprobe import loaded_by_scripts

REPO = Path(__file__).resolve().parent.parent
SCRIPTS = sorted((REPO / "workflow_scripts").glob("*.py"))


@pytest.fixture(scope="module")
def runtime_closure():
    return loaded_by_scripts(REPO)


def test_static_closure_equals_what_python_loads(runtime_closure):
    for script in SCRIPTS:
        assert imports.code_inputs(script.relative_to(REPO), REPO) == runtime_closure[script.name], script.name


def test_every_rule_declares_exactly_its_scripts_closure(runtime_closure):
    table = rule_table(REPO, config_overrides={"budget": "smoke"})
    with_script = {r: d for r, d in table.items() if d["script"]}
    assert len(with_script) >= 40
    for rule, d in sorted(with_script.items()):
        assert d["code"] is not None, f"rule {rule} has no code input"
        assert d["code"] == runtime_closure[d["script"]], rule


def test_bookkeeping_packages_hold_no_code():
    """The exempt package __init__ files (never declared) must not be able to change a result (records
    and files, the atomic write and sha256 it writes and hashes with, are the exempt code)."""
    for name in imports.EXEMPT - {"embodied_snap.lineage.records", "embodied_snap.files"}:
        tree = ast.parse(imports.module_file(name, REPO).read_text())
        body = [n for n in tree.body if not (isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant))]
        assert body == [], name


def test_relative_and_from_imports(tmp_path):
    pkg = tmp_path / "embodied_snap"
    for f, text in {
        "__init__.py": "",
        "a.py": "from . import b\nfrom .sub import c as C\n",
        "b.py": "def f():\n    from .sub.d import g  # a lazy import counts too\n",
        "sub/__init__.py": "",
        "sub/c.py": "import numpy\nfrom .. import lineage\n",
        "sub/d.py": "g = 1\n",
        "lineage/__init__.py": "",
        "lineage/records.py": "from embodied_snap import e\n",  # exempt: not followed
        "e.py": "",
        "unused.py": "",
    }.items():
        (pkg / f).parent.mkdir(parents=True, exist_ok=True)
        (pkg / f).write_text(text)
    (tmp_path / "workflow_scripts").mkdir()
    (tmp_path / "workflow_scripts/s.py").write_text(
        "import json\nfrom embodied_snap.a import x\nfrom embodied_snap.lineage.records import tracked\n")
    assert imports.code_inputs("workflow_scripts/s.py", tmp_path) == [
        "embodied_snap/a.py", "embodied_snap/b.py", "embodied_snap/sub/__init__.py", "embodied_snap/sub/c.py",
        "embodied_snap/sub/d.py"]


def test_the_saved_scan_follows_every_source(tmp_path):
    """The scan is saved (imports.CACHE) and read back by the next parse while no source changed; an
    edited module is scanned again, so its new import reaches the rules at once."""
    pkg = tmp_path / "embodied_snap"
    pkg.mkdir()
    for f in ("__init__.py", "a.py", "b.py"):
        (pkg / f).write_text("")
    (tmp_path / "workflow_scripts").mkdir()
    (tmp_path / "workflow_scripts/s.py").write_text("from embodied_snap import a\n")

    def parse():  # a new process: the scan kept in memory is gone
        for f in (imports._scanned, imports._closure, imports._imported):
            f.cache_clear()
        return imports.code_inputs("workflow_scripts/s.py", tmp_path)

    assert parse() == ["embodied_snap/a.py"]
    saved = json.loads((tmp_path / imports.CACHE).read_text())
    assert saved["scripts"] == {"workflow_scripts/s.py": ["embodied_snap.a"]}
    # read back, not scanned: a changed saved entry is what the next parse gives
    saved["scripts"]["workflow_scripts/s.py"] = []
    (tmp_path / imports.CACHE).write_text(json.dumps(saved))
    assert parse() == []
    (pkg / "a.py").write_text("from . import b\n")
    assert parse() == ["embodied_snap/a.py", "embodied_snap/b.py"]
