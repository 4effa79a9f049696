"""Provenance records: one JSON file per finished job (DESIGN.md section 5).

Every workflow script wraps its work in `tracked(snakemake)`. On success the job's record lands
in `results/provenance/<rule>/<wildcards>.json` with each input and output file, its sha256,
size and mtime, the code that ran, params, code and package versions, times and host.
Records are not Snakemake outputs: they describe jobs, they are not data. `esnap audit`,
`esnap check-separation` and the PROV export read only these records (and the files on disk).

Also here, because audit, separation and export all need them: which raw group a path belongs
to, and the group table (evidence set, category, role) from `raw_data/index.csv` and
`results/splits/split.csv`, read with `csv` so that `esnap audit` does not pay for pandas.
"""

from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import json
import os
import re
import socket
import subprocess
import sys
import tempfile
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path

RECORDS_DIR = "results/provenance"
INDEX_CSV = "raw_data/index.csv"
SPLIT_CSV = "results/splits/split.csv"
TWIN_TRUTH = "raw_data/twin_truth.json"
# The pinned dependencies whose versions can change a number (pyproject.toml).
PACKAGES = (
    "snakemake", "mujoco", "numpy", "pandas", "pyarrow", "pandera", "scipy",
    "scikit-learn", "statsmodels", "cma", "torch", "matplotlib",
)
# A raw recording file: raw_data/groups/<group_id>/<file>.
_GROUP_RE = re.compile(r"(?:^|/)raw_data/groups/([^/]+)/([^/]+)$")


def group_of(path: str) -> tuple[str, str] | None:
    """(group_id, file name) if `path` is a raw recording file, else None."""
    m = _GROUP_RE.search(path)
    return (m.group(1), m.group(2)) if m else None


def is_code(path: str) -> bool:
    """Package modules and workflow scripts are code inputs, recorded apart from data."""
    return path.startswith("embodied_snap/") or path.startswith("workflow_scripts/")


def sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


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


def record_path(rule: str, wildcards: dict, root: str | Path = ".") -> Path:
    # '/' in a wildcard value would make a subdirectory; escape it.
    name = ",".join(f"{k}={str(v).replace('/', '%2F')}" for k, v in sorted(wildcards.items())) or "_"
    return Path(root) / RECORDS_DIR / rule / f"{name}.json"


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")


def write_record(rule, wildcards, inputs, outputs, params, started, root=".", *, log=(),
                 finished=None) -> Path:
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
        params=_jsonable(params or {}),
        code_version=code_version(root),
        packages=package_versions(),
        python=sys.version.split()[0],
        started=started,
        finished=finished or _now(),
        host=socket.gethostname(),
    )
    path = record_path(rule, wildcards, root)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(rec, f, indent=1)
            f.write("\n")
        os.replace(tmp, path)  # atomic: a reader sees the old record or the new, never half
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _script_path(root: Path) -> str | None:
    """The workflow script that is running. Snakemake runs a copy named
    `.snakemake/scripts/tmpXXXX.<name>`; the source is workflow_scripts/<name>."""
    name = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    m = re.match(r"tmp[^.]*\.(.+)$", name)
    cand = f"workflow_scripts/{m.group(1) if m else name}"
    return cand if name and (root / cand).is_file() else None


@contextmanager
def tracked(smk, root="."):
    """Wrap a workflow script's work: `with tracked(snakemake): ...`.

    The old record goes first, so a failed job never leaves a record that vouches for outputs it
    did not write. On success the record is written; on an exception nothing is. It yields a list:
    a job that writes files Snakemake does not declare (the simulated rig's recordings) adds them.
    """
    root = Path(root)
    wildcards = {k: str(v) for k, v in _named(getattr(smk, "wildcards", None)).items() if k != "_"}
    rp = record_path(smk.rule, wildcards, root)
    rp.unlink(missing_ok=True)
    started = _now()
    undeclared: list[str] = []
    yield undeclared
    inputs = _flat(smk.input)
    script = _script_path(root)
    if script and script not in inputs:
        inputs.append(script)
    write_record(smk.rule, wildcards, inputs, _flat(smk.output) + undeclared, _named(getattr(smk, "params", None)),
                 started, root, log=_flat(getattr(smk, "log", None)))


def load_records(root=".") -> dict[str, dict]:
    """Output path -> the record of the job that wrote it (each record also gets `_record`, its own
    path). Where two records claim a path (a rule renamed), the later-finished wins."""
    root = Path(root)
    out: dict[str, dict] = {}
    for f in sorted((root / RECORDS_DIR).glob("*/*.json")):
        try:
            rec = json.loads(f.read_text())
        except (OSError, ValueError):
            continue  # a record being replaced right now; the rename makes this rare
        rec["_record"] = f.relative_to(root).as_posix()
        for o in rec.get("outputs", []):
            old = out.get(o["path"])
            if old is None or old.get("finished", "") <= rec.get("finished", ""):
                out[o["path"]] = rec
    return out


def load_groups(root=".") -> dict[str, dict]:
    """group_id -> {evidence_set, category, session, role}: index.csv, roles from split.csv.

    Without a split, roles follow the design: a non-dynamics group's role is its evidence set;
    a sealed-category dynamics group is sealed; other dynamics groups stay 'dynamics'."""
    root = Path(root)
    groups: dict[str, dict] = {}
    if (root / INDEX_CSV).exists():
        with open(root / INDEX_CSV, newline="") as f:
            for r in csv.DictReader(f):
                es, cat = r.get("evidence_set", ""), r.get("category", "")
                role = es if es != "dynamics" else ("sealed" if cat == "sealed" else "dynamics")
                groups[r["group_id"]] = dict(evidence_set=es, category=cat,
                                             session=r.get("session", ""), role=role)
    if (root / SPLIT_CSV).exists():
        with open(root / SPLIT_CSV, newline="") as f:
            for r in csv.DictReader(f):
                g = groups.setdefault(r["group_id"], dict(evidence_set="unknown", category="",
                                                          session="", role=""))
                g["role"] = r["role"]
    return groups
