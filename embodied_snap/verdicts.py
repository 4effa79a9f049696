"""The gate's verdicts while the workflow builds its DAG (rules/common.smk).

The workflow checks every group with validate.validate_group before any job may read it, so a
bad recording stops the run before a single result is touched. Building the DAG happens on every
`snakemake` call, so a passed group is remembered by what decides its verdict: its files' size
and mtime (as Snakemake itself judges change), its index.csv row, the gate's limits and the
gate's own code, with its recordings' sha256, so the rule that no recording is in two groups
reads no file of a remembered group. A rebuild re-checks only groups whose key changed; a
rejection is never cached.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path

from .io import write_json
from .rawformat import GROUP_FILES, RecordingError, group_paths
from .validate import ONE_RECORDING_RULE, RECORDINGS, Limits, check_one_recording, validate_group

# The modules whose code decides a verdict (this one: what a remembered pass holds).
_CODE = ("validate.py", "rawschema.py", "rawformat.py", "io.py", "verdicts.py")


class Verdicts:
    def __init__(self, raw_dir, limits: Limits, rows: dict, cache: str | Path | None):
        self.raw, self.limits, self.rows = raw_dir, limits, rows
        self.path = Path(cache) if cache else None
        h = hashlib.sha256(json.dumps(asdict(limits), sort_keys=True, default=list).encode())
        for name in _CODE:
            h.update((Path(__file__).parent / name).read_bytes())
        self.version = h.hexdigest()
        # gid -> its key and its recordings' sha256 (what the one-recording rule compares)
        self.passed: dict[str, dict] = {}
        self.seen: dict[str, dict] = {}  # passed in this process: its manifest entry
        if self.path and self.path.exists():
            try:
                saved = json.loads(self.path.read_text())
                if saved.get("version") == self.version:
                    self.passed = {g: v for g, v in saved["passed"].items() if _remembered(v)}
            except (ValueError, KeyError, TypeError, AttributeError):
                pass  # an unreadable cache is an empty one

    def _stat(self, gid: str):
        """Its files by name (GROUP_FILES) with their stats, or None: missing or outside the raw
        directory (the gate says which)."""
        try:
            return {name: (p, p.stat()) for name, p in zip(GROUP_FILES, group_paths(self.raw, gid).values())}
        except (OSError, ValueError):
            return None

    def check(self, group_ids) -> None:
        """Raise the gate's RecordingError for the first group that breaks a rule: each group on its
        own (a recording that is an earlier group's very file refused before it is read), then one
        recording in one group over them all (validate.check_one_recording, on sha256)."""
        ids, new, inodes = list(group_ids), False, {}
        for gid in ids:
            if gid in self.seen:
                continue
            files = self._stat(gid)
            for name in RECORDINGS if files else ():
                p, s = files[name]
                # size and mtime too: one file whatever a filesystem makes of its inode numbers
                other = inodes.setdefault((s.st_dev, s.st_ino, s.st_size, s.st_mtime_ns), (gid, p))
                if other[0] != gid:
                    raise RecordingError(p, gid, f"the same file as {other[1]} of group {other[0]}", ONE_RECORDING_RULE)
            st = [(s.st_size, s.st_mtime_ns) for _, s in files.values()] if files else None
            key = st and hashlib.sha256(json.dumps([self.rows.get(gid), st], default=str).encode()).hexdigest()
            hit = self.passed.get(gid)
            if key and hit and hit["key"] == key:
                entry = {"group_id": gid, "files": {n: {"path": str(files[n][0]), "sha256": hit["sha256"][n]}
                                                    for n in RECORDINGS}}
            else:
                entry = validate_group(self.raw, gid, self.rows.get(gid), limits=self.limits)
                if key:
                    sha = {n: entry["files"][n]["sha256"] for n in RECORDINGS}
                    self.passed[gid], new = {"key": key, "sha256": sha}, True
            self.seen[gid] = entry
        if new and self.path:
            write_json({"version": self.version, "passed": self.passed}, self.path)
        check_one_recording(self.seen[gid] for gid in ids)


def _remembered(v) -> bool:
    """A pass as check() writes it (anything else in the file is judged again)."""
    return (isinstance(v, dict) and isinstance(v.get("key"), str) and isinstance(v.get("sha256"), dict)
            and all(isinstance(v["sha256"].get(n), str) for n in RECORDINGS))


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


# What the workflow keeps beside a run: the verdicts already passed (Verdicts' cache), and the
# record a simulated-rig acquisition job writes once its shard is recorded (rules/acquire.smk).
GATE_CACHE = ".snakemake/esnap/gate.json"
ACQUIRED = "results/twin/acquired/{shard}.json"


def workflow_gate(config: dict):
    """The gate as the workflow runs it before its DAG (rules/common.smk), in the run's directory:
    gate_tree with the remembered verdicts; with the simulated rig, a shard not recorded yet is
    left to its validate_shard job. Returns (plan, verdicts)."""
    twin = config["raw_data"]["source"] == "twin"

    def recorded(shard):
        return not twin or Path(ACQUIRED.format(shard=shard)).exists()

    return gate_tree(config, config["raw_data"]["dir"], GATE_CACHE, recorded=recorded)


def check_tree(config: dict, raw_dir, partial: bool = False):
    """`esnap validate`: exactly what the workflow checks before its DAG (gate_tree), on every
    group; `partial`: of a tree holding part of the corpus (gate_tree). Returns the plan."""
    return gate_tree(config, raw_dir, partial=partial)[0]
