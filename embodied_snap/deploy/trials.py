"""The deployment index: which trials enter `<raw>/deployment/index.csv` and which are listed in
`aborted.json` with their cause. One gate for both rigs: the simulated rig's rule hands it the
trials it ran; in the lab, `esnap deploy-index` collects what `esnap deploy --out` left on disk.

Runs on the analysis machine (pandas, the recording gate), never on the lab PC: `esnap deploy`
does not import it.
"""

from __future__ import annotations

import json
from pathlib import Path

from .. import rawformat as RF
from ..io import parquet_rows, write_json
from ..rawformat import RecordingError
from ..validate import Limits, check_one_recording, validate_group


def gate(raw, trials: list[dict], limits: Limits) -> tuple[list[dict], list[dict]]:
    """trials: index rows of complete trials, or {group_id, cause} of aborted ones. Returns (rows
    that pass the recording gate of docs/data.md, aborted + rejected with their cause). A trial
    whose recording an earlier one already holds (a copied or linked take) is rejected: one
    recording, one trial of Table II."""
    rows, aborted, passed = [], [], []
    for r in trials:
        if "cause" in r:
            aborted.append(r)
            continue
        try:
            entry = validate_group(raw, r["group_id"], r, limits=limits)  # with the labels Table II reads (gate.labels)
            check_one_recording([*passed, entry])
        except RecordingError as e:  # kept out of the index with its reason, like an aborted trial
            aborted.append(dict(group_id=r["group_id"], cause=f"rejected by the gate: {e}"))
            continue
        passed.append(entry)
        rows.append(r)
    return rows, aborted


def write(rows: list[dict], aborted: list[dict], planned: int, index, aborted_path) -> None:
    """index.csv and aborted.json (each written whole, through a temporary file)."""
    write_json(dict(planned=planned, recorded=len(rows), aborted=sorted(aborted, key=lambda a: a["group_id"])),
               aborted_path)
    RF.write_index(rows, index)


def lab_trials(raw) -> list[dict]:
    """Every trial `esnap deploy --out raw` left: an index row per group folder (from its meta.json
    and recordings; the gate then checks them) and the cause of each abort record."""
    raw = Path(raw)
    out = []
    for meta_path in sorted(raw.glob("groups/*/meta.json")):
        gid = meta_path.parent.name
        try:
            p = RF.group_paths(raw, gid)  # first: a file linked out of the tree is refused unread
        except RF.RecordingError as e:
            out.append(dict(group_id=gid, cause=str(e)))
            continue
        try:
            meta = RF.read_meta(p["meta"])
        except (OSError, ValueError):  # the gate names what is wrong with it
            meta = {}
        out.append(dict(group_id=gid, evidence_set=meta.get("evidence_set"), category=meta.get("category"),
                        session=meta.get("session"), recorded_at=meta.get("recorded_at"),
                        **{f"n_{k}": parquet_rows(p[k]) for k in ("mocap", "servo") if p[k].exists()}))
    recorded = {t["group_id"] for t in out}
    for a in sorted(raw.glob("aborted/*.json")):
        rec = json.loads(a.read_text())
        if rec["group_id"] in recorded:  # aborted, then repeated under the same id: the repeat counts
            continue
        out.append(dict(group_id=rec["group_id"], cause=rec["cause"]))
    return out
