"""The sealed test set cannot move by accident (paper IV-A: 20 sealed groups, one evaluation).

Its membership is recorded once, when the dynamics corpus is first split: the ids of the sealed
groups with their evidence set, category and the sha256 of each recording file. The record lives
beside the recordings (`<raw_dir>/sealed.json`), so deleting results/ does not silently record a
new one. Every later run checks it while the plan is read: a sealed group that changed category
or role, left, arrived or was re-recorded stops the run with one line, until the user re-seals
explicitly with `esnap seal`, which says what the new sealed set is and records it.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from .files import sha256
from .io import write_json
from .rawformat import GROUP_FILES, RecordingError, group_paths, raw_file

RECORD = "sealed.json"
RULE = "sealed set is fixed; re-seal with `esnap seal` if intended"


def current(raw_dir, plan: pd.DataFrame) -> dict:
    """The sealed set of this plan as it would be recorded."""
    out = {}
    for r in plan[plan.role == "sealed"].sort_values("group_id").itertuples():
        paths = dict(zip(GROUP_FILES, group_paths(raw_dir, r.group_id).values()))
        out[r.group_id] = dict(
            evidence_set=r.evidence_set,
            category=r.category,
            role=r.role,
            sha256={f: sha256(p) for f, p in paths.items() if p.exists()},
        )
    return out


def record_path(raw_dir) -> Path:
    return Path(raw_dir) / RECORD


def check(raw_dir, plan: pd.DataFrame, partial: bool = False) -> None:
    """Raise a one-line RecordingError if the sealed set differs from its record (none: pass).
    `partial` (a tree holding part of the corpus, `esnap validate --partial`): a recorded sealed
    group the tree does not hold (yet) is not asked for; every one it holds is checked as always,
    and a sealed group it holds that the record lacks still stops it."""
    path = raw_file(raw_dir, RECORD)  # a link out is refused before it is opened
    if not path.exists():
        return
    try:
        rec = json.loads(path.read_text())["groups"]
    except (ValueError, KeyError, TypeError) as e:
        raise RecordingError(path, "-", f"unreadable record: {e}", RULE) from None
    rows = plan.set_index("group_id")
    for gid, was in sorted(rec.items()):
        if gid not in rows.index:
            if partial:
                continue
            raise RecordingError(path, gid, "sealed group is no longer in the plan", RULE)
        now = rows.loc[gid]
        if (now.category, now.role) != (was["category"], was["role"]):
            raise RecordingError(
                path,
                gid,
                f"sealed group is now {now.category} ({now.role}), was " f"{was['category']} ({was['role']})",
                RULE,
            )
    now = current(raw_dir, plan)
    for gid, cur in now.items():
        if gid not in rec:
            raise RecordingError(path, gid, f"{cur['category']} group joined the sealed set", RULE)
        for f, h in rec[gid]["sha256"].items():
            if cur["sha256"].get(f) != h:
                raise RecordingError(
                    group_paths(raw_dir, gid)[f.split(".")[0]], gid, "recording of a sealed group changed", RULE
                )


def seal(raw_dir, plan: pd.DataFrame, how: str) -> dict:
    """Record the sealed set of `plan` (overwrites an earlier record: only by explicit request)."""
    groups = current(raw_dir, plan)
    write_json({"groups": groups, "sealed_by": how}, record_path(raw_dir))
    return groups
