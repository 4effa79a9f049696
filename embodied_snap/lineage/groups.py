"""The group table of a run, and which raw group a path belongs to: what the audit, the separation
checks and the PROV export classify recordings by. Read with `csv`, so `esnap audit` does not pay
for pandas. The raw directory is the configured one (records.raw_dir_of)."""

from __future__ import annotations

import csv
from pathlib import Path

from .records import DEFAULT_RAW

SPLIT_CSV = "results/splits/split.csv"


def index_csv(raw: str = DEFAULT_RAW) -> str:
    return f"{raw}/index.csv"


def twin_truth(raw: str = DEFAULT_RAW) -> str:
    return f"{raw}/twin_truth.json"


def deployment_dir(raw: str = DEFAULT_RAW) -> str:
    """The deployment trials' own recording tree (written after the manifest was exported)."""
    return f"{raw}/deployment"


def group_of(path: str, raw: str = DEFAULT_RAW) -> tuple[str, str] | None:
    """(group_id, file name) if `path` (relative to the root) is a recording file of `raw`."""
    head = f"{raw}/groups/"
    if not path.startswith(head):
        return None
    parts = path[len(head):].split("/")
    return (parts[0], parts[1]) if len(parts) == 2 else None


def load_groups(root=".", raw: str = DEFAULT_RAW) -> dict[str, dict]:
    """group_id -> {evidence_set, category, session, role}: index.csv, roles from split.csv.

    Without a split, roles follow the design: a non-dynamics group's role is its evidence set;
    a sealed-category dynamics group is sealed; other dynamics groups stay 'dynamics'."""
    root = Path(root)
    groups: dict[str, dict] = {}
    if (root / index_csv(raw)).exists():
        with open(root / index_csv(raw), newline="") as f:
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
