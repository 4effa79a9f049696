"""`esnap audit RESULT`: which recordings fed a result, which did not, and is it still current.

Answers from the provenance records alone (no Snakemake, no pandas, so it stays fast): walk from
RESULT's record through the records of the jobs that wrote its inputs down to raw group files.
Every job that wrote an input is descended (the raw manifest too: a figure of the manifest was fed
by every recording), except the gates (policy.GATES: the separation proof and the PROV export),
which reports list as inputs only to run after them; they are listed in the chain, not descended.

Stale: a file whose recorded sha256 no longer matches the disk. Size and mtime_ns are compared
first and the file is hashed only when one of them changed, so a paper-budget audit (thousands of
raw files) costs a stat per file.
"""

from __future__ import annotations

import json
import os
import re
import time
from collections import deque
from pathlib import Path

from ..files import sha256
from .groups import group_of, load_groups
from .policy import GATES, label
from .records import last_config, load_records, raw_dir_of


def _norm(result: str, root: Path) -> str:
    p = Path(result)
    if p.is_absolute():
        p = Path(os.path.relpath(p, root.resolve()))
    return p.as_posix().removeprefix("./").rstrip("/")


class _Disk:
    """Compares recorded file entries with the disk, statting and hashing each path at most once."""

    def __init__(self, root: Path):
        self.root, self.stat, self.hash = root, {}, {}

    def check(self, e: dict) -> str | None:
        """None when the file still matches its record, else why not."""
        p = e["path"]
        if p not in self.stat:
            try:
                st = os.stat(self.root / p)
                self.stat[p] = (st.st_size, st.st_mtime_ns)
            except OSError:
                self.stat[p] = None
        st = self.stat[p]
        if st is None:
            return "missing on disk"
        if st == (e.get("bytes"), e.get("mtime_ns")):
            return None
        if p not in self.hash:
            self.hash[p] = sha256(self.root / p)
        return None if self.hash[p] == e["sha256"] else "sha256 changed"


def audit(result: str, root=".", config: dict | None = None, check_disk: bool = True,
          records: dict | None = None) -> dict:
    """`config`: the run's config (default: the one the last run recorded), for the raw directory.
    `check_disk=False`: lineage only, no staleness (a job inside the run, which must not read
    files it did not declare). `records`: load_records(root), when the caller has them."""
    t0 = time.perf_counter()
    root = Path(root)
    records = load_records(root) if records is None else records
    raw = raw_dir_of(config if config is not None else last_config(root, records))
    result = _norm(result, root)
    starts = [result] if result in records else sorted(p for p in records if p.startswith(result + "/"))
    groups_idx = load_groups(root, raw)
    disk = _Disk(root)

    jobs, seen_rec, seen_path = [], set(), set(starts)
    fed: dict[str, dict] = {}  # group -> {file name: sha256}, the files a job really read
    unread: dict[str, dict] = {}  # groups a job was given (declared) but did not read
    other_sources: dict[str, str] = {}  # source files that are not recordings (index, reference values)
    missing, stale = [], []
    todo = deque(starts)
    if not starts:
        missing.append(result)
    while todo:
        p = todo.popleft()
        rec = records.get(p)
        if rec is None:
            missing.append(p)
            continue
        if rec["_record"] in seen_rec:
            continue
        seen_rec.add(rec["_record"])
        gate = rec["rule"] in GATES
        jobs.append(dict(label=label(rec["rule"], rec.get("wildcards", {})), rule=rec["rule"],
                         wildcards=rec.get("wildcards", {}), record=rec["_record"],
                         finished=rec.get("finished"), code_version=rec.get("code_version"),
                         host=rec.get("host"), gate=gate))
        # A gate vouches only for its outputs; its inputs are not RESULT's lineage.
        entries = rec.get("outputs", []) + ([] if gate else rec.get("inputs", []) + rec.get("code", []))
        for e in entries if check_disk else ():
            why = disk.check(e)
            if why:
                stale.append(dict(path=e["path"], why=why, record=rec["_record"]))
        if gate:
            continue
        # What the job really read (records before reads were recorded: every input).
        reads = set(rec["reads"]) if rec.get("reads") is not None else None
        for e in rec.get("inputs", []):
            q = e["path"]
            go = group_of(q, raw)
            if go:
                (fed if reads is None or q in reads else unread).setdefault(go[0], {})[go[1]] = e["sha256"]
            elif reads is not None and q not in reads and not any(r.startswith(q + "/") for r in reads):
                continue  # declared only to run after it (a validation record): not lineage
            elif not q.startswith("results/"):
                # Only results/ is derived; anything else (raw_data/index.csv, reference/*.yaml) is a
                # source: a leaf, already checked against its recorded hash above.
                other_sources[q] = e["sha256"]
            elif q not in seen_path:
                seen_path.add(q)
                todo.append(q)

    sets: dict[str, dict] = {}
    for g, d in groups_idx.items():
        s = sets.setdefault(d["evidence_set"], dict(n_total=0, fed={}, not_fed=[], roles={}))
        s["n_total"] += 1
        if g not in fed:
            s["not_fed"].append(g)
    for g, files in fed.items():
        d = groups_idx.get(g, dict(evidence_set="unknown (not in index.csv)", role=""))
        s = sets.setdefault(d["evidence_set"], dict(n_total=0, fed={}, not_fed=[], roles={}))
        s["fed"][g] = dict(role=d["role"], files=dict(sorted(files.items())))
        s["roles"][d["role"]] = s["roles"].get(d["role"], 0) + 1
    for s in sets.values():
        s["n_fed"] = len(s["fed"])
        s["fed"] = dict(sorted(s["fed"].items()))
        s["not_fed"].sort()
    # Stale entries of one path can come from several records; keep the first of each.
    uniq = list({(x["path"], x["record"]): x for x in stale}.values())
    return dict(
        result=result,
        record=records[result]["_record"] if result in records else None,
        outputs=starts,  # RESULT itself, or the recorded files under a RESULT directory
        stale=bool(uniq or missing),
        stale_files=uniq,
        missing_records=missing,
        evidence_sets=dict(sorted(sets.items(), key=lambda kv: (-kv[1]["n_fed"], kv[0]))),
        not_fed=sorted(k for k, s in sets.items() if s["n_fed"] == 0),
        n_groups_fed=len(fed),
        given_unread=sorted(set(unread) - set(fed)),
        other_sources=dict(sorted(other_sources.items())),
        jobs=jobs,
        hosts=sorted({j["host"] for j in jobs if j["host"]}),  # a cluster run's jobs ran on several
        excluded=_excluded(root),
        elapsed_s=round(time.perf_counter() - t0, 3),
    )


def _excluded(root: Path) -> list[dict]:
    """Groups the user left out of the run (raw_data.exclude), as the raw manifest names them."""
    try:
        return json.loads((root / "results/raw/manifest.json").read_text()).get("excluded", [])
    except (OSError, ValueError):
        return []


def compact_ids(ids) -> str:
    """dyn_0001, dyn_0002, dyn_0003, dyn_0007 -> 'dyn_0001-0003, dyn_0007'."""
    parsed, other = [], []
    for g in sorted(ids):
        m = re.fullmatch(r"(.*?)(\d+)", g)
        if m:
            parsed.append((m.group(1), len(m.group(2)), int(m.group(2))))
        else:
            other.append(g)
    parsed.sort()
    out, i = [], 0
    while i < len(parsed):
        pre, w, a = parsed[i]
        j = i
        while j + 1 < len(parsed) and parsed[j + 1][:2] == (pre, w) and parsed[j + 1][2] == parsed[j][2] + 1:
            j += 1
        b = parsed[j][2]
        out.append(f"{pre}{a:0{w}d}" + (f"-{b:0{w}d}" if b != a else ""))
        i = j + 1
    return ", ".join(out + other)


def format_audit(report: dict, hashes: bool = False) -> str:
    r = report
    head = (f"record {r['record']}" if r["record"] else
            f"directory of {len(r['outputs'])} recorded files" if r["outputs"] else "no provenance record")
    L = [f"RESULT {r['result']}  ({head})"]
    if r["stale"]:
        L.append(f"stale: YES - {len(r['stale_files'])} file(s) changed since recorded, "
                 f"{len(r['missing_records'])} without a record")
        for x in r["stale_files"][:5]:
            L.append(f"  {x['path']}: {x['why']} (recorded in {x['record']})")
        for p in r["missing_records"][:5]:
            L.append(f"  {p}: no provenance record")
    else:
        L.append("stale: no (every recorded hash matches the disk)")
    if len(r.get("hosts", ())) > 1:
        L.append(f"jobs ran on {len(r['hosts'])} hosts: {', '.join(r['hosts'])}")
    fed = {k: s for k, s in r["evidence_sets"].items() if s["n_fed"]}
    L.append(f"fed by {r['n_groups_fed']} raw group(s) from {len(fed)} evidence set(s):")
    for es, s in fed.items():
        roles = ", ".join(f"{k} {v}" for k, v in sorted(s["roles"].items()) if k and k != es)
        L.append(f"  {es:<18} {s['n_fed']:>4}/{s['n_total']:<4} {compact_ids(s['fed'])}"
                 + (f"  [{roles}]" if roles else ""))
        if s["n_fed"] < s["n_total"]:
            L.append(f"  {'':<18} not fed: {compact_ids(s['not_fed'])}")
        if hashes:
            for g, d in s["fed"].items():
                L.append(f"    {g}: " + ", ".join(f"{f} {h[:12]}" for f, h in d["files"].items()))
    if r.get("given_unread"):
        L.append(f"given but never read: {compact_ids(r['given_unread'])}")
    if r["not_fed"]:
        L.append("did not feed it: " + ", ".join(
            f"{k} (0/{r['evidence_sets'][k]['n_total']})" for k in r["not_fed"]))
    for x in r.get("excluded", []):
        L.append(f"excluded: {x['group_id']}, {x['reason']}")
    for p, h in r["other_sources"].items():
        L.append(f"also read: {p} sha256 {h[:12]}")
    L.append(f"job chain ({len(r['jobs'])} jobs, RESULT first):")
    by_rule: dict[str, list] = {}
    for j in r["jobs"]:
        by_rule.setdefault(j["rule"], []).append(j)
    for rule, js in by_rule.items():
        wc = [",".join(f"{k}={v}" for k, v in j["wildcards"].items()) for j in js if j["wildcards"]]
        shown = ", ".join(wc[:4]) + (f", ... (+{len(wc) - 4})" if len(wc) > 4 else "")
        tag = "  [gate: not descended]" if js[0]["gate"] else ""
        L.append(f"  {rule}" + (f" x{len(js)}" if len(js) > 1 else "") + (f": {shown}" if shown else "") + tag)
    L.append(f"({r['elapsed_s']} s)")
    return "\n".join(L)
