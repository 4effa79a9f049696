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
            validate_group(self.raw, gid, self.rows.get(gid), limits=self.limits)
            if key is not None:
                self.passed[gid], new = key, True
                self.seen.add(gid)
        if new and self.path:
            write_json({"version": self.version, "passed": self.passed}, self.path)


def index_rows(raw_dir, plan, pattern: str) -> dict:
    """What each group must agree with: its index.csv row, or its plan row while no index.csv
    exists (the simulated rig's first run writes it after recording, from the recordings)."""
    from .validate import read_index

    rows = {
        r["group_id"]: r for r in plan[["group_id", "evidence_set", "category", "session"]].to_dict("records")
    }
    if (Path(raw_dir) / "index.csv").exists():
        rows.update({r["group_id"]: r for r in read_index(raw_dir, pattern).to_dict("records")})
    return rows


def gate_tree(config: dict, raw_dir, cache=None, recorded=None, partial: bool = False):
    """The gate before any DAG, one function for the workflow (rules/common.smk) and `esnap
    validate` (check_tree), with the same inputs whatever the source: the plan (index.csv, ids,
    folders, exclusions), every recorded group not excluded against its index.csv row (row
    counts included), then the sealed set against its record. `recorded(shard)` says whether a
    shard is on disk yet (the simulated rig records during the run; the workflow judges the rest
    when its acquisition completes); None: every shard. `partial` (`esnap validate --partial`, a
    tree holding part of the corpus): the same gate on every group, without the split (and its
    size rule), and the sealed groups the tree holds against their record. Returns (plan, verdicts)."""
    from . import sealed
    from .plan import load_plan

    plan = load_plan(config, raw_dir, partial=partial)
    limits = Limits.from_config(config)
    verdicts = Verdicts(raw_dir, limits, index_rows(raw_dir, plan, limits.group_id_pattern), cache)
    on_disk = plan if recorded is None else plan[[bool(recorded(s)) for s in plan.shard]]
    verdicts.check(on_disk.group_id)
    if recorded is None or all(recorded(s) for s in plan[plan.role == "sealed"].shard.unique()):
        sealed.check(raw_dir, plan, partial=partial)
    return plan, verdicts


def check_tree(config: dict, raw_dir, partial: bool = False):
    """`esnap validate`: exactly what the workflow checks before its DAG (gate_tree), on every
    group; `partial`: of a tree holding part of the corpus (gate_tree). Returns the plan."""
    return gate_tree(config, raw_dir, partial=partial)[0]
