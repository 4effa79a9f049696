"""Provenance records: one JSON file per finished job (docs/lineage.md).

Every workflow script wraps its work in `tracked(snakemake)`. On success the job's record lands
in `results/provenance/<rule>/<wildcards>.json` with each input and output file, its sha256,
size and mtime, the code that ran, params, code and package versions, times and host, and what the
job really touched: every file it opened under the workflow root (`reads`) and every package
module it loaded (`modules`). A job that opened a file under `results/` or the raw directory that
it did not declare, or loaded a package module that is not among its code inputs, fails with one
line: every run checks its own declarations.

Reads are seen through Python's audit hook (the `open` event): `open`, `json`, `np.load`,
`torch.load`, pandas' csv reader, and parquet through `embodied_snap.io` (pyarrow's own C++ reads
are invisible to the hook, hence that one reader). In a Snakemake job the hook is installed at the
interpreter's start, before the script's first line, by the start-up hook the workflow puts on its
jobs' PYTHONPATH (STARTUP, `job_environment`), so a read anywhere in a script or in a package
module's import is seen and checked like one inside `tracked()`, and a job without that start fails.

Records are not Snakemake outputs: they describe jobs, they are not data. `esnap audit`,
`esnap check-separation` and the PROV export read only these records (and the files on disk).
This module uses the standard library alone (and embodied_snap.files, the package's one atomic write
and file sha256, standard library too) and is not a declared code input of any rule
(lineage/imports.py): it changes records, never a result.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import re
import socket
import subprocess
import sys
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path

from ..files import sha256, write_text

RECORDS_DIR = "results/provenance"
CONFIG_DIR = f"{RECORDS_DIR}/config"  # the config each run used, by sha256 (records name theirs)
# The pinned dependencies whose versions can change a number (pyproject.toml).
PACKAGES = (
    "snakemake", "mujoco", "numpy", "pandas", "pyarrow", "pandera", "scipy",
    "scikit-learn", "statsmodels", "cma", "torch", "matplotlib",
)
PACKAGE = "embodied_snap"
# Loaded by every job for the bookkeeping itself; never declared (lineage/imports.py).
EXEMPT_MODULES = frozenset({PACKAGE, f"{PACKAGE}.files", f"{PACKAGE}.lineage", f"{PACKAGE}.lineage.records"})
# Folders under the root whose reads are neither data nor checked: logs and benchmarks the job
# writes, code (declared and checked as modules), and hidden folders (.snakemake, .venv, .git).
_NOT_DATA = ("logs/", "benchmarks/", f"{PACKAGE}/", "workflow_scripts/")
DEFAULT_RAW = "raw_data"
# Written after the run, by `snakemake --report` and its browser check: they describe the run, no
# job writes them, so they have no record (docs/report.md).
AFTER_RUN = ("results/report.html", "results/report.png")


class UndeclaredInput(RuntimeError):
    """A job touched what it did not declare: one line, `<file>: <what> (rule: <rule>)`."""


def raw_dir_of(config: dict | None) -> str:
    """The raw directory a config names, as a clean relative path."""
    raw = ((config or {}).get("raw_data") or {}).get("dir", DEFAULT_RAW)
    return os.path.normpath(str(raw)).replace(os.sep, "/")


def is_code(path: str) -> bool:
    """Package modules and workflow scripts are code inputs, recorded apart from data."""
    return path.startswith("embodied_snap/") or path.startswith("workflow_scripts/")


def _rel(path: str | Path, root: Path) -> str:
    p = Path(path)
    if p.is_absolute():
        p = Path(os.path.relpath(p, root.resolve()))
    return p.as_posix().removeprefix("./")


def file_entries(paths, root: str | Path = ".") -> list[dict]:
    """[{path, sha256, bytes, mtime_ns}] for each path; directories are expanded to their files
    (a directory output has no hash of its own, its files do)."""
    root = Path(root)
    out = []
    for p in paths:
        rel = _rel(p, root)
        full = root / rel
        files = sorted(f for f in full.rglob("*") if f.is_file()) if full.is_dir() else [full]
        for f in files:
            st = f.stat()
            out.append(dict(path=(Path(rel) / f.relative_to(full)).as_posix() if full.is_dir() else rel,
                            sha256=sha256(f),
                            bytes=st.st_size, mtime_ns=st.st_mtime_ns))
    return out


_code_version: dict | None = None


def code_version(root: str | Path = ".") -> dict:
    """Git commit and dirty flag of the checkout, or the installed package version outside git."""
    global _code_version
    if _code_version is None:
        try:
            run = lambda *a: subprocess.run(["git", *a], cwd=root, capture_output=True, text=True,
                                            check=True, timeout=20).stdout.strip()
            # -uno: untracked files (raw_data, results) are not code and would make status slow.
            _code_version = dict(git_commit=run("rev-parse", "HEAD"),
                                 dirty=bool(run("status", "--porcelain", "-uno")))
        except (OSError, subprocess.SubprocessError):
            _code_version = dict(package_version=_version("embodied-snap"))
    return _code_version


def _version(pkg: str) -> str | None:
    try:
        return metadata.version(pkg)
    except metadata.PackageNotFoundError:
        return None


def package_versions() -> dict:
    return {p: _version(p) for p in PACKAGES}


def _jsonable(v):
    """Params as JSON: containers kept, anything else as its string."""
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    return str(v)


def _named(nl) -> dict:
    """A Snakemake Namedlist as a dict; unnamed positional entries go under '_'."""
    if nl is None:
        return {}
    d = {k: v for k, v in nl.items()} if hasattr(nl, "items") else {}
    if not d and len(nl):
        d = {"_": list(nl)}
    return d


def _flat(nl) -> list[str]:
    out = []
    for v in (nl or []):
        out.extend(_flat(v) if isinstance(v, (list, tuple)) else [str(v)])
    return out


# Rules the workflow writes once per shard (rules/acquire.smk: the shard's recordings are the
# declared outputs of a rule of its own, named `<rule>_<shard>`); records, the lineage's DAG and
# the separation policy read each as one job of the rule with the shard as its wildcard.
PER_SHARD = ("twin_acquire",)


def per_shard_name(rule: str, shard: str) -> str:
    """The workflow's name of one shard's rule (`instance` reads it back)."""
    return f"{rule}_{shard}"


def instance(rule: str, wildcards: dict) -> tuple[str, dict]:
    """A job's rule and wildcards as the policy names them: a per-shard rule as the rule with its
    `shard` wildcard, every other rule as it is."""
    for r in PER_SHARD:
        if rule.startswith(r + "_") and not wildcards:
            return r, {"shard": rule[len(r) + 1:]}
    return rule, wildcards


def record_path(rule: str, wildcards: dict, root: str | Path = ".") -> Path:
    # '/' in a wildcard value would make a subdirectory; escape it.
    name = ",".join(f"{k}={str(v).replace('/', '%2F')}" for k, v in sorted(wildcards.items())) or "_"
    return Path(root) / RECORDS_DIR / rule / f"{name}.json"


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")


def write_config(config: dict, root=".") -> str:
    """Store a run's config once under CONFIG_DIR; return its sha256 (records name it)."""
    text = json.dumps(_jsonable(config), sort_keys=True, indent=1) + "\n"
    sha = hashlib.sha256(text.encode()).hexdigest()
    path = Path(root) / CONFIG_DIR / f"{sha}.json"
    if not path.exists():
        write_text(path, text)  # atomic: several nodes may store the same config at once
    return sha


def write_record(rule, wildcards, inputs, outputs, params, started, root=".", *, log=(),
                 finished=None, reads=None, modules=None, config=None) -> Path:
    """Write the record of one job (the same as `tracked` does, without snakemake)."""
    root = Path(root)
    wildcards = {str(k): str(v) for k, v in dict(wildcards or {}).items()}
    ins = [_rel(p, root) for p in inputs]
    rec = dict(
        rule=rule,
        wildcards=wildcards,
        inputs=file_entries([p for p in ins if not is_code(p)], root),
        code=file_entries([p for p in ins if is_code(p)], root),
        outputs=file_entries(outputs, root),
        log=[_rel(p, root) for p in log],
        reads=sorted(reads) if reads is not None else None,
        modules=file_entries(sorted(modules), root) if modules is not None else None,
        raw_dir=raw_dir_of(config),
        config_sha256=write_config(config, root) if config is not None else None,
        params=_jsonable(params or {}),
        code_version=code_version(root),
        packages=package_versions(),
        python=sys.version.split()[0],
        started=started,
        finished=finished or _now(),
        host=socket.gethostname(),
    )
    path = record_path(rule, wildcards, root)
    # atomic, also when jobs on several nodes write the same record at once (embodied_snap.files)
    write_text(path, json.dumps(rec, indent=1) + "\n")
    return path


def _script_path(root: Path) -> str | None:
    """The workflow script that is running. Snakemake runs a copy named
    `.snakemake/scripts/tmpXXXX.<name>`; the source is workflow_scripts/<name>."""
    name = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    m = re.match(r"tmp[^.]*\.(.+)$", name)
    cand = f"workflow_scripts/{m.group(1) if m else name}"
    return cand if name and (root / cand).is_file() else None


# --- what a job really touched -----------------------------------------------------------------

_opened: set[str] | None = None  # paths opened for reading while a job is watched
_hooked = False
_from_start = False  # this interpreter's watch began at its start (the start-up hook)
# The start-up hook's folder: its sitecustomize starts the watch in a job's interpreter before the
# job's script runs (docs/lineage.md, "From the interpreter's start").
STARTUP = Path(__file__).with_name("startup")


def job_environment(env=os.environ) -> dict[str, str]:
    """What the workflow sets for its jobs (rules/common.smk): PYTHONPATH with STARTUP first, the
    rest of `env`'s kept after it (once: the Snakefile may be read more than once in a process)."""
    rest = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and p != str(STARTUP)]
    return {"PYTHONPATH": os.pathsep.join([str(STARTUP), *rest])}


def watch_from_start() -> None:
    """The start-up hook's call, in a job's interpreter before its script's first line."""
    global _from_start
    _watch()
    _from_start = True


def _audit(event: str, args: tuple) -> None:
    # Runs on every audit event of the process: return at once unless a job is watching an open.
    if event != "open" or _opened is None:
        return
    try:
        path, mode, flags = args
        if path is None or isinstance(path, int):
            return  # an fd: the file was opened (and seen) before
        ro = (flags & os.O_ACCMODE) == os.O_RDONLY if mode is None else not any(c in mode for c in "wax+")
        if ro:
            _opened.add(os.fsdecode(path))
    except Exception:  # noqa: BLE001 -- a hook that raises would break the job's own open()
        pass


def _watch() -> None:
    """Start collecting reads; a watch already running (started with a job's interpreter) keeps what
    it saw since."""
    global _opened, _hooked
    if not _hooked:
        sys.addaudithook(_audit)  # hooks cannot be removed; _opened = None turns it off
        _hooked = True
    if _opened is None:
        _opened = set()


def _stop_watching(root: Path) -> list[str]:
    """Files under root the job opened for reading (relative paths), data only."""
    global _opened
    opened, _opened = _opened or set(), None
    base = os.path.join(str(root.resolve()), "")
    out = set()
    for p in opened:
        # a prefix test, not relpath: a job watched from its start opens a few thousand files
        # (its imports), nearly all outside root or under .venv
        a = os.path.abspath(p)
        if not a.startswith(base):
            continue
        rel = a[len(base):].replace(os.sep, "/")
        if rel.startswith(_NOT_DATA) or any(c.startswith(".") for c in rel.split("/")):
            continue
        out.add(rel)
    return sorted(out)


def loaded_modules() -> list[str]:
    """Source files (package-relative paths, e.g. embodied_snap/io.py) of the package modules
    loaded in this process, less the bookkeeping's own (EXEMPT_MODULES)."""
    out = []
    for name, mod in list(sys.modules.items()):
        if name in EXEMPT_MODULES or not name.startswith(PACKAGE + "."):
            continue
        f = getattr(mod, "__file__", None) or ""
        out.append("/".join(name.split(".")) + ("/__init__.py" if f.endswith("__init__.py") else ".py"))
    return sorted(out)


def check_declared(rule: str, declared: list[str], reads: list[str], modules: list[str], raw: str) -> None:
    """Fail (one line) on a read under results/ or the raw directory, or a loaded package module,
    that the job did not declare. Provenance records themselves are metadata, not data: the
    lineage jobs read them all."""
    decl = set(declared)
    dirs = tuple(d.rstrip("/") + "/" for d in declared)
    for p in reads:
        if not (p.startswith("results/") or p.startswith(raw + "/")) or p.startswith(RECORDS_DIR + "/"):
            continue
        if p not in decl and not p.startswith(dirs):
            raise UndeclaredInput(f"{p}: read by rule {rule} but not among its declared inputs "
                                  "(rule: a job reads only what it declares)")
    for m in modules:
        if m not in decl:
            raise UndeclaredInput(f"{m}: loaded by rule {rule} but not among its code inputs "
                                  "(rule: code inputs are the script's imports, lineage/imports.py)")


def check_watched(rule: str, script: str | None = None) -> None:
    """Fail (one line) if a Snakemake job's watch did not begin at its interpreter's start: what it
    read, or loaded, before `tracked()` went unseen (the job's PYTHONPATH lacked STARTUP). Watched
    from the start, no package module can have been loaded before the watch."""
    if _in_job() and not _from_start:
        hook = (STARTUP / "sitecustomize.py").relative_to(STARTUP.parents[2]).as_posix()
        raise UndeclaredInput(f"{script or sys.argv[0]}: run by rule {rule} without the watch from its start (rule: a "
                              f"job's reads are watched from its interpreter's start by {hook}, which the "
                              "workflow puts on its jobs' PYTHONPATH, docs/lineage.md)")


@contextmanager
def tracked(smk, root=".", check_modules: bool = True):
    """Wrap a workflow script's work: `with tracked(snakemake): ...`.

    The old record goes first, so a failed job never leaves a record that vouches for outputs it
    did not write. On success the job's reads and modules are checked against its declarations
    (UndeclaredInput, one line) and the record is written; on an exception nothing is. Every file
    a job writes is one of its declared outputs (the simulated rig's recordings too, rules/acquire.smk).
    `check_modules=False` is for tests that run it inside a process (pytest) that has loaded other
    modules than the job's.
    """
    root = Path(root)
    wildcards = {k: str(v) for k, v in _named(getattr(smk, "wildcards", None)).items() if k != "_"}
    rule, wildcards = instance(smk.rule, wildcards)
    rp = record_path(rule, wildcards, root)
    rp.unlink(missing_ok=True)
    started = _now()
    _watch()
    try:
        yield
    finally:
        reads = _stop_watching(root)
    config = dict(getattr(smk, "config", None) or {})
    inputs = [_rel(p, root) for p in _flat(smk.input)]
    outputs = _flat(smk.output)
    log = _flat(getattr(smk, "log", None))
    modules = loaded_modules() if check_modules else []
    own = {_rel(p, root) for p in outputs + log}
    script = _script_path(root)
    try:
        if check_modules:
            check_watched(rule, script)
        check_declared(rule, inputs + sorted(own), reads, modules, raw_dir_of(config))
    except UndeclaredInput as e:
        sys.exit(f"error: {e}")  # one line, in the job's log
    if script and script not in inputs:
        inputs.append(script)
    write_record(rule, wildcards, inputs, outputs, _named(getattr(smk, "params", None)),
                 started, root, log=log, reads=reads, modules=modules, config=config)


def load_records(root=".", errors: list | None = None) -> dict[str, dict]:
    """Output path -> the record of the job that wrote it (each record also gets `_record`, its own
    path). Where two records claim a path (a rule renamed), the later-finished wins. A record that
    cannot be read is skipped here and, when `errors` is given, appended to it (path, why). One gone
    between the listing and its reading belongs to a job beside this one that has just started (a
    job removes its old record first, `tracked`): missing, as if listed a moment later."""
    root = Path(root)
    out: dict[str, dict] = {}
    for f in sorted((root / RECORDS_DIR).glob("*/*.json")):
        if f.parent.name == "config":
            continue
        try:
            rec = json.loads(f.read_text())
            if not isinstance(rec, dict) or "rule" not in rec:
                raise ValueError("not a provenance record")
        except FileNotFoundError:
            continue
        except (OSError, ValueError) as e:
            if errors is not None:
                errors.append((f.relative_to(root).as_posix(), f"{type(e).__name__}: {e}"))
            continue
        rec["_record"] = f.relative_to(root).as_posix()
        for o in rec.get("outputs", []):
            old = out.get(o["path"])
            if old is None or old.get("finished", "") <= rec.get("finished", ""):
                out[o["path"]] = rec
    return out


def last_config(root=".", records: dict | None = None) -> dict | None:
    """The config of the most recently finished recorded job (the last run's), or None.
    `records`: load_records(root), when the caller has them already."""
    root = Path(root)
    recs = [r for r in (records if records is not None else load_records(root)).values() if r.get("config_sha256")]
    if not recs:
        return None
    last = max(recs, key=lambda r: r.get("finished", ""))
    return json.loads((root / CONFIG_DIR / f"{last['config_sha256']}.json").read_text())


def _in_job() -> bool:
    # Snakemake's preamble defines `snakemake` in the script's namespace before its first line; no
    # other process (pytest, esnap) has it, and none of them is watched from its start.
    return hasattr(sys.modules.get("__main__"), "snakemake")
