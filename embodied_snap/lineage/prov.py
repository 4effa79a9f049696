"""The run's provenance as W3C PROV-JSON (docs/design.md section 5), built with the `prov` package.

Files are entities (sha256, bytes), jobs are activities (used / wasGeneratedBy, start and end
times), the code that ran is used with role esnap:code, and every acquisition group is a
prov:Collection of its raw files with its evidence set, category, role and held-out status
(lineage/policy.py decides what is held out), so a PROV tool can answer "which held-out group
reached this figure" without knowing this project.
"""

from __future__ import annotations

import datetime as dt
import json
import os
from pathlib import Path

from prov.model import ProvDocument

from ..files import write_text
from .groups import group_of, load_groups
from .policy import held_out
from .records import last_config, load_records, raw_dir_of

NAMESPACES = {
    "esnap": "urn:embodied-snap:ns#",  # attributes and types of this project
    "file": "urn:embodied-snap:file:",  # files, by path relative to the workflow root
    "job": "urn:embodied-snap:job:",  # one finished job, <rule>/<wildcards>
    "group": "urn:embodied-snap:group:",  # one acquisition group
}


def _time(s):
    try:
        return dt.datetime.fromisoformat(s)
    except (TypeError, ValueError):  # a hand-written record without a proper time
        return None


def build(root=".", raw: str | None = None) -> ProvDocument:
    """The PROV document of the recorded run; `raw`: the raw directory (default: the last run's)."""
    root = Path(root)
    loaded = load_records(root)
    raw = raw or raw_dir_of(last_config(root, loaded))
    doc = ProvDocument()
    ns = {k: doc.add_namespace(k, uri) for k, uri in NAMESPACES.items()}
    code_t = ns["esnap"]["Code"]  # a qualified name, not the string "esnap:Code"
    records = {r["_record"]: r for r in loaded.values()}
    entities: dict[str, object] = {}

    def entity(e: dict, code=False):
        p = e["path"]
        if p not in entities:
            attrs = {"esnap:sha256": e["sha256"], "esnap:bytes": e["bytes"], "esnap:path": p}
            if code:
                attrs["prov:type"] = code_t
            entities[p] = doc.entity(f"file:{p}", attrs)
        return entities[p]

    for key, r in sorted(records.items()):
        cv = r.get("code_version") or {}
        act = doc.activity(
            f"job:{key.removeprefix('results/provenance/').removesuffix('.json')}",
            _time(r.get("started")), _time(r.get("finished")),
            {"esnap:rule": r["rule"], "esnap:wildcards": json.dumps(r.get("wildcards", {}), sort_keys=True),
             "esnap:params": json.dumps(r.get("params", {}), sort_keys=True), "esnap:host": r.get("host", ""),
             "esnap:code_version": json.dumps(cv, sort_keys=True), "esnap:record": key},
        )
        for e in r.get("inputs", []):
            doc.used(act, entity(e))
        for e in r.get("code", []):
            doc.used(act, entity(e, code=True), other_attributes={"prov:role": code_t})
        for e in r.get("outputs", []):
            doc.wasGeneratedBy(entity(e), act)

    groups = load_groups(root, raw)
    members: dict[str, list[str]] = {}
    for p in entities:
        g = group_of(p, raw)
        if g:
            members.setdefault(g[0], []).append(p)
    for gid in sorted(set(groups) | set(members)):
        d = groups.get(gid, dict(evidence_set="unknown", category="", session="", role=""))
        coll = doc.collection(f"group:{gid}", {
            "esnap:evidence_set": d["evidence_set"], "esnap:category": d["category"],
            "esnap:session": d["session"], "esnap:role": d["role"],
            "esnap:held_out": held_out(d["role"], d["evidence_set"]),
        })
        paths = members.get(gid)
        if not paths:  # a group no recorded job touched: its files on disk, unhashed
            gdir = root / raw / "groups" / gid
            paths = [f"{raw}/groups/{gid}/{f}" for f in sorted(os.listdir(gdir))] if gdir.is_dir() else []
            for p in paths:
                entities.setdefault(p, doc.entity(f"file:{p}", {"esnap:path": p}))
        for p in sorted(paths):
            doc.hadMember(coll, entities[p])
    return doc


def export(root=".", out="results/lineage/prov.json", raw: str | None = None) -> Path:
    return write_text(Path(root) / out, build(root, raw).serialize(format="json", indent=1))
