"""How many checks the test suite holds, at a git revision or in the work tree: for a change that
moves, merges or splits tests and must not lose an assertion.

    python bench/test_census.py [REV ...]

Counts, in tests/*.py, the `assert` statements and the `pytest.raises` / `pytest.fail` calls (a
static count: a parametrised test's assertions count once, however many cases it runs). With no
REV, the work tree.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path


def sources(rev: str | None) -> dict[str, str]:
    if rev is None:
        return {str(p): p.read_text() for p in sorted(Path("tests").glob("*.py"))}
    names = subprocess.run(["git", "ls-tree", "-r", "--name-only", rev, "tests/"], capture_output=True,
                           text=True, check=True).stdout.split()
    return {f: subprocess.run(["git", "show", f"{rev}:{f}"], capture_output=True, text=True, check=True).stdout
            for f in names if f.endswith(".py") and "/" not in f.removeprefix("tests/")}


def census(source: str) -> tuple[int, int]:
    asserts = checks = 0
    for node in ast.walk(ast.parse(source)):
        asserts += isinstance(node, ast.Assert)
        checks += (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                   and node.func.attr in ("raises", "fail") and isinstance(node.func.value, ast.Name)
                   and node.func.value.id == "pytest")
    return asserts, checks


def main(argv: list[str]) -> int:
    for rev in argv or [None]:
        files = sources(rev)
        counts = [census(s) for s in files.values()]
        print(f"{rev or 'work tree'}: {len(files)} files, {sum(a for a, _ in counts)} assert statements, "
              f"{sum(c for _, c in counts)} pytest.raises/fail")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
