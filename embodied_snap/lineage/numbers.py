"""A number's lineage: `esnap audit CLAIM_ID` and `esnap audit FILE:KEY`, and the ledger's
`artifact` and `fed_by` cells, from one function (docs/lineage.md, "A number's lineage").

A claim's `source` names the artifact and key it was read from (embodied_snap.sources). Its
recordings are the groups of the fit that wrote that artifact: the artifact's own `recordings`
(the groups used, and those its fit's rules dropped, each with the rule), checked against what the
fit's jobs really read; an artifact without them (a simulated result built from fits) is fed by
every group its jobs read (`esnap audit FILE`). Stale: the artifact's lineage changed on disk, or
the artifact or the stage's claims table changed after the ledger read them.
"""

from __future__ import annotations

import csv
import json
import time
from collections import Counter
from pathlib import Path

from ..files import sha256
from ..sources import RECORDINGS, parse_source, read_key
from .audit import audit, compact_ids
from .groups import deployment_dir, group_of, load_groups
from .records import last_config, load_records, raw_dir_of

LEDGER = "results/tables/claims.csv"


class NumberError(ValueError):
    """A claim or a FILE:KEY that cannot be audited: one line."""


def _index(root: Path, raw: str) -> dict[str, str]:
    """group_id -> evidence set, of the run's recordings and of its deployment trials."""
    out = {g: d["evidence_set"] for g, d in load_groups(root, raw).items()}
    dep = root / deployment_dir(raw) / "index.csv"
    if dep.exists():
        with open(dep, newline="") as f:
            out.update({r["group_id"]: r.get("evidence_set") or "deployment" for r in csv.DictReader(f)})
    return out


def _json(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


class Numbers:
    """The lineage of a run's numbers. The group index, each artifact's file audit and its fit's
    recordings are read once and shared by every number read from that artifact (the ledger's
    161 rows come from a few dozen artifacts). `check_disk`: the stale check, as `esnap audit`."""

    def __init__(self, root=".", records: dict | None = None, check_disk: bool = False):
        self.root = Path(root)
        self.records = load_records(self.root) if records is None else records
        self.check_disk = check_disk
        self.raw = raw_dir_of(last_config(self.root, self.records))
        self.index = _index(self.root, self.raw)
        self.totals = Counter(self.index.values())
        self._artifacts: dict[str, dict] = {}

    def _read_groups(self, rep: dict, art: str) -> set[str]:
        """Groups the artifact's jobs read: the file audit's, and those its own job read in the
        deployment's trial tree, which the audit does not walk."""
        trials = deployment_dir(self.raw)
        out = {g for s in rep["evidence_sets"].values() for g in s["fed"]}
        return out | {go[0] for p in (self.records.get(art) or {}).get("reads") or () if (go := group_of(p, trials))}

    def artifact(self, art: str) -> dict:
        """One artifact's recordings (its fit's, or every group its jobs read) and job chain."""
        if art in self._artifacts:
            return self._artifacts[art]
        rep = audit(art, self.root, check_disk=self.check_disk, records=self.records)
        value = _json(self.root / art)
        rec = value.get(RECORDINGS) if isinstance(value, dict) else None
        if rec is not None:
            read = self._read_groups(rep, art)
            unread = [g for g in rec["used"] if g not in read]
            if unread:
                raise NumberError(f"{art}: its recordings name group {unread[0]}, which its jobs never read "
                                  "(rule: a fit records only the groups it read)")
            used, dropped, how = list(rec["used"]), dict(rec["dropped"]), "the groups its fit used"
        else:
            used = [g for s in rep["evidence_sets"].values() for g in s["fed"]]
            dropped, how = {}, "every group its jobs read"
        self._artifacts[art] = dict(path=art, how=how, used=sorted(used), dropped=dropped, record=rep["record"],
                                    stale_files=rep["stale_files"], missing_records=rep["missing_records"],
                                    jobs=rep["jobs"])
        return self._artifacts[art]

    def lineage(self, source: str) -> dict:
        """The artifacts, keys, recordings (by evidence set) and job chains behind one `source` cell."""
        keys: dict[str, list[str]] = {}
        for art, key in parse_source(source):
            keys.setdefault(art, []).append(key)
        arts = [dict(self.artifact(art), keys=ks) for art, ks in keys.items()]
        sets: dict[str, dict] = {}
        for g in sorted({g for a in arts for g in a["used"]}):
            es = self.index.get(g, "unknown (in no index.csv)")
            sets.setdefault(es, dict(used=[], n_total=self.totals.get(es, 0)))["used"].append(g)
        return dict(source=source, artifacts=arts,
                    evidence_sets=dict(sorted(sets.items(), key=lambda kv: (-len(kv[1]["used"]), kv[0]))))


def lineage(source: str, root=".") -> dict:
    """One number's lineage (Numbers(root).lineage, for a single source)."""
    return Numbers(root).lineage(source)


def fed_by(lin: dict) -> str:
    """The ledger's cell: 'servo_calibration 291/291; ...' by evidence set, most groups first."""
    return "; ".join(f"{es} {len(s['used'])}/{s['n_total']}" for es, s in lin["evidence_sets"].items())


def artifacts(lin: dict) -> str:
    return " ".join(a["path"] for a in lin["artifacts"])


# --- esnap audit CLAIM_ID | FILE:KEY ------------------------------------------------------------------


def _ledger_rows(root: Path) -> list[dict]:
    try:
        with open(root / LEDGER, newline="") as f:
            return list(csv.DictReader(f))
    except OSError:
        raise NumberError(f"{LEDGER}: no claims ledger under {root} (run the workflow first)") from None


def _changed_since_read(root: Path, records: dict, reader: str, path: str) -> str | None:
    """Why `path` on disk is not the file the job that wrote `reader` read, or None."""
    rec = records.get(reader)
    e = next((e for e in (rec or {}).get("inputs", []) if e["path"] == path), None)
    if e is None:
        return None
    try:
        return None if sha256(root / path) == e["sha256"] else f"changed after {reader} was written"
    except OSError:
        return "missing on disk"


def audit_number(what: str, root=".") -> dict:
    """CLAIM_ID (a row of the ledger) or FILE:KEY."""
    t0 = time.perf_counter()
    root = Path(root)
    records = load_records(root)
    row = None
    if ":" in what and "/" in what:
        art, _, key = what.partition(":")
        value = _json(root / art)
        if value is None:
            raise NumberError(f"{art}: no such JSON artifact under {root}")
        try:
            ours = read_key(value, key)
        except (KeyError, IndexError, ValueError, TypeError):
            raise NumberError(f"{art}: no key {key!r} in it (keys are names joined by '/')") from None
        rows = _ledger_rows(root) if (root / LEDGER).exists() else []
        source, claims = what, [r["claim_id"] for r in rows if what in r.get("source", "").split()]
    else:
        rows = [r for r in _ledger_rows(root) if r["claim_id"] == what]
        if not rows:
            raise NumberError(f"{what}: no such claim in {LEDGER} (a claim id, or FILE:KEY)")
        row = rows[0]
        source, ours, claims = row["source"], row["ours"], [what]
    lin = Numbers(root, records, check_disk=True).lineage(source)
    stale = []
    for a in lin["artifacts"]:
        stale += [f"{x['path']}: {x['why']}" for x in a["stale_files"]]
        stale += [f"{p}: no provenance record" for p in a["missing_records"]]
    if row is not None:
        table = f"results/{row['stage']}/claims.csv"
        for a in lin["artifacts"]:
            why = _changed_since_read(root, records, table, a["path"])
            if why:
                stale.append(f"{a['path']}: {why}")
        why = _changed_since_read(root, records, LEDGER, table)
        if why:
            stale.append(f"{table}: {why}")
    return dict(what=what, claims=claims, row=row, ours=ours, lineage=lin, stale=stale,
                elapsed_s=round(time.perf_counter() - t0, 3))


def format_lineage(lin: dict) -> list[str]:
    """The artifacts, keys, recordings and job chains of a number: the audit's body, and the
    report's page of each claim."""
    L = []
    for a in lin["artifacts"]:
        L.append(f"read from {a['path']} (record {a['record']}), key " + ", ".join(a["keys"]))
        L.append(f"  recordings: {a['how']}, {len(a['used'])}")
        for g, why in sorted(a["dropped"].items()):
            L.append(f"  dropped by the fit: {g} ({why})")
        L.append(f"  job chain ({len(a['jobs'])} jobs): " + ", ".join(dict.fromkeys(j["rule"] for j in a["jobs"])))
    L.append(f"fed by {sum(len(s['used']) for s in lin['evidence_sets'].values())} raw group(s) from "
             f"{len(lin['evidence_sets'])} evidence set(s):")
    for es, s in lin["evidence_sets"].items():
        L.append(f"  {es:<18} {len(s['used']):>4}/{s['n_total']:<4} {compact_ids(s['used'])}")
    return L


def claim_head(row: dict) -> list[str]:
    return [f"CLAIM {row['claim_id']}  ({row['section']}: {row['quantity']})",
            f"ours {row['ours']} {row['unit']}; paper {row['paper'] or '-'}; {row['status']}"]


def format_number(r: dict) -> str:
    row = r["row"]
    if row is not None:
        L = claim_head(row)
    else:
        L = [f"NUMBER {r['what']}", f"value {json.dumps(r['ours'])}" + (
            f"; in the ledger as {', '.join(r['claims'])}" if r["claims"] else "; no ledger row reads it")]
    L.append("stale: " + ("YES - " + "; ".join(r["stale"][:5]) if r["stale"] else
                          "no (the artifact is the one the ledger read, and its lineage matches the disk)"))
    L += format_lineage(r["lineage"])
    L.append(f"({r['elapsed_s']} s)")
    return "\n".join(L)
