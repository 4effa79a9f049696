"""A rule's code inputs: the package modules its workflow script imports, transitively.

Read statically (ast) from the source files, so the Snakefile needs to import nothing: every
`import` and `from ... import` of the `embodied_snap` package anywhere in a module counts, and
importing a submodule also runs its parent packages' `__init__.py`. The rules list these files as
inputs, so editing a module reruns exactly the jobs whose scripts reach it; at run time
`records.tracked` fails a job that loaded a package module not among them.

A script that builds the Snakemake DAG (through lineage/dag.py) also runs the workflow
definition, so the modules that the Snakefile and rules/*.smk import count for it too.

The provenance writer itself (`records`, the packages that hold it, and `files`, the atomic write
and file sha256 it writes records with) is left out: it changes the records, never a result, and
declaring it would rerun every job whenever it is edited.
"""

from __future__ import annotations

import ast
import hashlib
import json
from functools import lru_cache
from pathlib import Path

from ..files import write_text

PACKAGE = "embodied_snap"
# Every workflow script's modules, saved with the sizes and times of the sources they were read from:
# parsing ~200 modules is a fifth of a dry run, and their sources rarely change between two runs.
CACHE = ".snakemake/esnap-imports.json"  # the same for every budget (not parked by esnap budget)
# Loaded by every job for its own bookkeeping; never declared (see above).
EXEMPT = frozenset({PACKAGE, f"{PACKAGE}.files", f"{PACKAGE}.lineage", f"{PACKAGE}.lineage.records"})
DAG_MODULE = f"{PACKAGE}.lineage.dag"


@lru_cache(maxsize=None)  # the DAG build asks for the same modules once per rule
def module_file(name: str, root: Path) -> Path | None:
    """The source file of package module `name` under root, or None if it is not one."""
    rel = Path(*name.split("."))
    for p in (root / rel.with_suffix(".py"), root / rel / "__init__.py"):
        if p.is_file():
            return p
    return None


@lru_cache(maxsize=None)
def _is_package(name: str, root: Path) -> bool:
    return (root / Path(*name.split(".")) / "__init__.py").is_file()


@lru_cache(maxsize=None)
def _imported(path: Path, name: str, root: Path) -> frozenset[str]:
    """Package modules that the source at `path` (module `name`, or "" for a script) imports."""
    return _imports_in(path.read_text(), name, root)


@lru_cache(maxsize=None)
def workflow_imports(root: Path) -> frozenset[str]:
    """Package modules the workflow definition imports: the top-level `import`/`from` lines of
    the Snakefile and rules/*.smk (the rest of a .smk file is not Python)."""
    out: set[str] = set()
    for f in [root / "Snakefile", *sorted((root / "rules").glob("*.smk"))]:
        if f.is_file():
            lines = [ln for ln in f.read_text().splitlines() if ln.startswith(("import ", "from "))]
            out |= _imports_in("\n".join(lines), "", root)
    return frozenset(out)


def _imports_in(text: str, name: str, root: Path) -> frozenset[str]:
    tree = ast.parse(text)
    pkg = name if name and _is_package(name, root) else (name.rpartition(".")[0] if name else "")
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.add(mod)
            # `from pkg import sub` imports the submodule when `sub` is one
            out |= {f"{mod}.{a.name}" for a in node.names if module_file(f"{mod}.{a.name}", root)}
    mods = set()
    for m in out:
        if m == PACKAGE or m.startswith(PACKAGE + "."):
            parts = m.split(".")
            # a module runs its parent packages first
            mods |= {".".join(parts[:k]) for k in range(1, len(parts) + 1)}
    return frozenset(m for m in mods if module_file(m, root))


@lru_cache(maxsize=None)
def _closure(script: str, root: str) -> frozenset[str]:
    r = Path(root)
    todo = [m for m in _imported(r / script, "", r) if m not in EXEMPT]
    seen: set[str] = set()
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        seen.add(m)
        todo += [k for k in _imported(module_file(m, r), m, r) if k not in EXEMPT and k not in seen]
        if m == DAG_MODULE:
            todo += [k for k in workflow_imports(r) if k not in EXEMPT and k not in seen]
    return frozenset(seen)


def _sources(root: Path) -> str:
    """What every scan reads: each source's path, size and modification time, as one key."""
    files = [*(root / PACKAGE).rglob("*.py"), *(root / "workflow_scripts").glob("*.py"), root / "Snakefile",
             *(root / "rules").glob("*.smk")]
    stats = [(f.relative_to(root).as_posix(), st.st_size, st.st_mtime_ns)
             for f in sorted(files) if f.is_file() for st in [f.stat()]]
    return hashlib.sha256(json.dumps(stats).encode()).hexdigest()


@lru_cache(maxsize=None)
def _scanned(root: str) -> dict[str, list[str]]:
    """{workflow_scripts/<name>.py: its modules}: from CACHE while no source changed since it was
    written, else every script scanned and CACHE written again."""
    r = Path(root)
    key = _sources(r)
    try:
        saved = json.loads((r / CACHE).read_text())
        if saved["sources"] == key:
            return saved["scripts"]
    except (OSError, ValueError, KeyError, TypeError):
        pass  # no cache, or an unreadable one: scan
    scripts = {p.relative_to(r).as_posix(): sorted(_closure(p.relative_to(r).as_posix(), root))
               for p in sorted((r / "workflow_scripts").glob("*.py"))}
    try:
        write_text(r / CACHE, json.dumps({"sources": key, "scripts": scripts}))
    except OSError:
        pass  # a read-only checkout scans at every parse
    return scripts


def modules_of(script: str | Path, root: str | Path = ".") -> list[str]:
    """Dotted names of the package modules `script` (a path relative to root) reaches."""
    r = str(Path(root).resolve())
    saved = _scanned(r).get(Path(script).as_posix())
    return saved if saved is not None else sorted(_closure(str(script), r))


def code_inputs(script: str | Path, root: str | Path = ".") -> list[str]:
    """The source files (relative to root) of the modules `script` reaches, sorted."""
    r = Path(root).resolve()
    return sorted(module_file(m, r).relative_to(r).as_posix() for m in modules_of(script, r))
