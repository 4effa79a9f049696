"""The gate's verdicts while the workflow builds its DAG (rules/common.smk).

The workflow checks every group with validate.validate_group before any job may read it, so a
bad recording stops the run before a single result is touched. Building the DAG happens on every
`snakemake` call, so a passed group is remembered by what decides its verdict: its files' size
and mtime (as Snakemake itself judges change), its index.csv row, the gate's limits and the
gate's own code. A rebuild re-checks only groups whose key changed; a rejection is never cached.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path

from .rawformat import group_paths, write_json
from .validate import Limits, validate_group

# The modules whose code decides a verdict.
_CODE = ("validate.py", "rawschema.py", "rawformat.py", "io.py")


class Verdicts:
    def __init__(self, raw_dir, limits: Limits, rows: dict, cache: str | Path | None):
        self.raw, self.limits, self.rows = raw_dir, limits, rows
        self.path = Path(cache) if cache else None
        h = hashlib.sha256(json.dumps(asdict(limits), sort_keys=True, default=list).encode())
        for name in _CODE:
            h.update((Path(__file__).parent / name).read_bytes())
        self.version = h.hexdigest()
        self.passed: dict[str, str] = {}
        self.seen: set[str] = set()  # passed in this process: one DAG build asks for a group many times
        if self.path and self.path.exists():
            try:
                saved = json.loads(self.path.read_text())
                if saved.get("version") == self.version:
                    self.passed = dict(saved["passed"])
            except (ValueError, KeyError, TypeError):
                pass  # an unreadable cache is an empty one

    def _key(self, gid: str) -> str | None:
        try:
            st = [(s.st_size, s.st_mtime_ns) for s in (p.stat() for p in group_paths(self.raw, gid).values())]
        except (OSError, ValueError):
            return None  # missing or outside the raw directory: the gate says which
        return hashlib.sha256(json.dumps([self.rows.get(gid), st], default=str).encode()).hexdigest()

    def check(self, group_ids) -> None:
        """Raise the gate's RecordingError for the first group that breaks a rule."""
        new = False
        for gid in group_ids:
            if gid in self.seen:
                continue
            key = self._key(gid)
            if key is not None and self.passed.get(gid) == key:
                self.seen.add(gid)
                continue
            validate_group(self.raw, gid, self.rows.get(gid), self.limits)
            if key is not None:
                self.passed[gid], new = key, True
                self.seen.add(gid)
        if new and self.path:
            write_json({"version": self.version, "passed": self.passed}, self.path)


def index_rows(raw_dir, plan, pattern: str, use_index: bool = True) -> dict:
    """What each group must agree with: its index.csv row, or (use_index False, or before its
    index.csv is written) its plan row."""
    from .validate import read_index

    rows = {
        r["group_id"]: r for r in plan[["group_id", "evidence_set", "category", "session"]].to_dict("records")
    }
    if use_index and (Path(raw_dir) / "index.csv").exists():
        rows.update({r["group_id"]: r for r in read_index(raw_dir, pattern).to_dict("records")})
    return rows


def check_tree(config: dict, raw_dir):
    """What the workflow checks before its DAG, all at once (`esnap validate`): the plan, every
    group not excluded through the gate, the sealed set against its record. Returns the plan."""
    from . import sealed
    from .plan import load_plan

    plan = load_plan(config, raw_dir)
    limits = Limits.from_config(config)
    Verdicts(raw_dir, limits, index_rows(raw_dir, plan, limits.group_id_pattern), None).check(plan.group_id)
    sealed.check(raw_dir, plan)
    return plan
