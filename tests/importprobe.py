"""Which package modules each workflow script really loads, found by Python's own import
machinery (not by lineage/imports.py, which the tests check against it)."""

import json
import subprocess
import sys
from pathlib import Path

from embodied_snap.lineage.imports import EXEMPT

# Runs in a fresh interpreter: for each script, forget every package module, execute the script's
# own import statements (and, for a script that builds the DAG, the workflow definition's), and list
# the package modules Python loaded (their source files).
_PROBE = r"""
import ast, json, sys
from pathlib import Path
out = {}
smk = [l for f in ["Snakefile", *sorted(map(str, Path("rules").glob("*.smk")))]
       for l in Path(f).read_text().splitlines() if l.startswith(("import ", "from "))]
for path in sys.argv[1:]:
    for name in [m for m in sys.modules if m == "embodied_snap" or m.startswith("embodied_snap.")]:
        del sys.modules[name]
    tree = ast.parse(Path(path).read_text())
    for node in tree.body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            exec(compile(ast.Module([node], []), path, "exec"), {})
    if "embodied_snap.lineage.dag" in sys.modules:
        exec("\n".join(smk), {})
    out[Path(path).name] = sorted(
        "/".join(n.split(".")) + ("/__init__.py" if m.__file__.endswith("__init__.py") else ".py")
        for n, m in sys.modules.items() if n.startswith("embodied_snap.") or n == "embodied_snap")
print(json.dumps(out))
"""


def loaded_by_scripts(root: Path) -> dict[str, list[str]]:
    """{script file name: sorted package-relative source files it loads, less the exempt ones}."""
    scripts = sorted((root / "workflow_scripts").glob("*.py"))
    r = subprocess.run([sys.executable, "-c", _PROBE, *map(str, scripts)], cwd=root, capture_output=True,
                       text=True, env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stderr[-3000:]
    exempt = {"/".join(m.split(".")) + s for m in EXEMPT for s in (".py", "/__init__.py")}
    return {k: sorted(set(v) - exempt) for k, v in json.loads(r.stdout).items()}
