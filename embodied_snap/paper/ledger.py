"""One claims ledger: every stage's claims.csv side by side, each paper number judged against ours.

A stage's table is `results/<stage>/claims.csv` (claim_id, section, quantity, paper, ours, unit).
The ledger adds `agrees` (ours inside the paper's interval, or within the relative tolerance of
reference/paper_values.yaml where the paper gives a point value), `artifact` (the files the row's
`source`, artifact:key, names), `fed_by` (evidence sets and group counts of the recordings behind
that one number: lineage.numbers, the code of `esnap audit CLAIM_ID`) and, for a difference, the doc
that explains it.
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import pandas as pd

from ..lineage import numbers
from ..lineage.records import load_records
from ..reference import by_construction, tolerance
from ..sources import parse_source
from . import html
from .sections import section_key

COLUMNS = ("claim_id", "stage", "section", "quantity", "paper", "ours", "unit", "tolerance", "status",
           "agrees", "source", "artifact", "fed_by", "explained_in")
AUDIT = "audit-"  # the id prefix of a claim's audit section in claims.html
# status values; BY_CONSTRUCTION: the simulated rig agrees because one of its inputs came from this
# paper result (reference/paper_values.yaml `by_construction:`, docs/twin.md), never "agrees"
AGREES, DIFFERS, NO_PAPER, NOT_MEASURED = "agrees", "differs", "no paper value", "not measured"
BY_CONSTRUCTION = "by construction"
STATUSES = (AGREES, DIFFERS, BY_CONSTRUCTION, NOT_MEASURED, NO_PAPER)  # every status a row can have
TWIN_PROVENANCE = "docs/twin.md"  # where each simulated-rig number comes from


def parse(v: str):
    """A claims cell: None (empty), a float, a list of floats ('[a, b]' or '[a, b, c]'), an
    inequality ('<1e-10' -> ('<', 1e-10)), or a word (Table II's online correction "none"), which
    agrees only with the same word."""
    v = (v or "").strip()
    if not v:
        return None
    if re.fullmatch(r"[A-Za-z][A-Za-z ]*", v) and v.lower() not in ("nan", "inf", "infinity"):
        return v.lower()
    m = re.fullmatch(r"([<>]=?)\s*(\S+)", v)
    if m:
        return (m.group(1), float(m.group(2)))
    if v.startswith("["):  # an empty range ('[, ]': no value to take it from) is not measured
        return [float(x) for x in v.strip("[]").split(",") if x.strip()] or None
    return float(v)


def _near(o: float, p: float, tol: float) -> bool:
    return abs(o - p) <= tol * abs(p) if p else o == 0


def agrees(paper, ours, tol: float) -> bool | None:
    """None when either side is missing. The paper's value is a point, an interval [lo, hi], a
    value per section (three), or an inequality; ours is a point, a range (seeds, an interval) or a
    value per section:
    - point vs point: within `tol` relative; point vs our range: the range, widened by `tol`
      relative to the point, contains it;
    - interval vs point or values: every value inside; interval vs our interval: they overlap;
    - per section: section by section;
    - inequality: every value of ours satisfies it."""
    if paper is None or ours is None:
        return None
    if isinstance(paper, str) or isinstance(ours, str):
        return paper == ours
    vals = ours if isinstance(ours, list) else [ours]
    if any(math.isnan(x) for x in vals):
        return None
    if isinstance(paper, tuple):
        op, x = paper
        return all({"<": v < x, "<=": v <= x, ">": v > x, ">=": v >= x}[op] for v in vals)
    if isinstance(paper, list) and len(paper) == 2:
        lo, hi = paper
        if isinstance(ours, list) and len(ours) == 2:
            return ours[0] <= hi and ours[1] >= lo
        return all(lo <= v <= hi for v in vals)
    if isinstance(paper, list):
        return len(paper) == len(vals) and all(_near(o, p, tol) for o, p in zip(vals, paper, strict=True))
    if isinstance(ours, list) and len(ours) == 2:
        return ours[0] - tol * abs(paper) <= paper <= ours[1] + tol * abs(paper)
    return all(_near(v, paper, tol) for v in vals)


def _fed_by(*reps: dict) -> str:
    """Evidence sets, groups fed / total and split roles behind one or more audits, merged."""
    sets: dict[str, dict] = {}
    for rep in reps:
        for es, s in rep["evidence_sets"].items():
            d = sets.setdefault(es, dict(total=s["n_total"], fed={}))
            d["fed"].update({g: v["role"] for g, v in s["fed"].items()})
    parts = []
    for es, d in sorted(sets.items(), key=lambda kv: (-len(kv[1]["fed"]), kv[0])):
        if d["fed"]:
            roles: dict[str, int] = {}
            for r in d["fed"].values():
                roles[r] = roles.get(r, 0) + 1
            rs = ", ".join(f"{k} {v}" for k, v in sorted(roles.items()) if k and k != es)
            parts.append(f"{es} {len(d['fed'])}/{d['total']}" + (f" ({rs})" if rs else ""))
    return "; ".join(parts)


def _doc(stage: str, claim_id: str, root: Path) -> str:
    """The doc that explains a difference: one naming the claim id, else the stage's own doc."""
    docs = sorted((root / "docs").glob("*.md"))
    for d in docs:
        if claim_id in d.read_text():
            return d.relative_to(root).as_posix()
    own = root / "docs" / f"{stage}.md"
    return own.relative_to(root).as_posix() if own.exists() else ""


def ledger(files, root=".", simulated: bool = True) -> list[dict]:
    """The rows of results/tables/claims.csv, in the order of `files` and of each table. simulated:
    the recordings are the simulated rig's, so a claim one of its inputs was taken from agrees "by
    construction" (with a real rig's recordings it is judged like any other)."""
    root = Path(root)
    records = load_records(root)
    nums = numbers.Numbers(root, records)  # each artifact audited once, for all its rows
    rows = []
    for f in files:
        stage = Path(f).parent.name
        rec = records.get(f)
        if rec is None:
            raise ValueError(f"{f}: no provenance record (rule: every claims table comes from a recorded job)")
        # the artifacts its job read, or wrote (Table II's claims beside its summary)
        known = {e["path"] for e in rec.get("inputs", []) + rec.get("outputs", [])}
        with open(root / f, newline="") as fh:
            for r in csv.DictReader(fh):
                src = r.get("source") or ""
                bad = [a for a, _ in parse_source(src) if a not in known]
                if not src or bad:
                    raise ValueError(f"{f}: claim {r['claim_id']}: " + (f"source {bad[0]} is no input of its job" if bad
                                     else "no source") + " (rule: each claim names the artifact:key it was read from)")
                lin = nums.lineage(src)
                try:
                    p, o = parse(r["paper"]), parse(r["ours"])
                except ValueError as e:
                    raise ValueError(f"{f}: claim {r['claim_id']}: {e} (rule: numbers, [lo, hi] or <x)") from None
                tol = tolerance(stage, r["claim_id"])
                ok = agrees(p, o, tol)
                status = NO_PAPER if p is None else NOT_MEASURED if ok is None else AGREES if ok else DIFFERS
                built = simulated and status == AGREES and by_construction(stage, r["claim_id"])
                status = BY_CONSTRUCTION if built else status
                rows.append(dict(
                    claim_id=r["claim_id"], stage=stage, section=r["section"], quantity=r["quantity"],
                    paper=r["paper"], ours=r["ours"], unit=r["unit"], tolerance=tol, status=status,
                    agrees="" if ok is None else ok, source=src, artifact=numbers.artifacts(lin),
                    fed_by=numbers.fed_by(lin), _lineage=lin,
                    explained_in=(_doc(stage, r["claim_id"], root) if status == DIFFERS
                                  else TWIN_PROVENANCE if built else ""),
                ))
    return rows


def counts(rows: list[dict]) -> dict:
    n = [r for r in rows if r["status"] != NO_PAPER]
    diff = [r for r in rows if r["status"] == DIFFERS]
    return dict(paper_numbers=len(n), agree=sum(r["status"] == AGREES for r in rows), differ=len(diff),
                by_construction=sum(r["status"] == BY_CONSTRUCTION for r in rows),
                not_measured=sum(r["status"] == NOT_MEASURED for r in rows),
                unexplained=sum(not r["explained_in"] for r in diff))


def count_line(rows: list[dict]) -> str:
    c = counts(rows)
    return (f"{c['paper_numbers']} paper numbers, {c['agree']} reproduced within tolerance, "
            f"{c['by_construction']} agree by construction (a simulated-rig input taken from that result), "
            f"{c['differ']} differ, "
            f"each difference linked to the doc that explains it ({c['unexplained']} without one), "
            f"{c['not_measured']} not measured in this run")


def markdown(rows: list[dict]) -> str:
    """results/tables/claims.md: the count line, then one table per paper section."""
    out = ["# Claims ledger", "", count_line(rows), ""]
    by: dict[str, list[dict]] = {}
    for r in rows:
        by.setdefault(r["section"], []).append(r)
    link = lambda r: f"[{r['explained_in']}](../../{r['explained_in']})" if r["explained_in"] else ""  # noqa: E731
    for sec in sorted(by, key=section_key):
        rs = by[sec]
        c = counts(rs)
        out += [f"## {sec}", "", f"{c['paper_numbers']} paper numbers, {c['agree']} within tolerance, "
                f"{c['by_construction']} by construction, {c['differ']} differ", ""]
        t = pd.DataFrame([[str(v) for v in (r["claim_id"], r["quantity"], r["paper"], r["ours"], r["unit"],
                                            r["status"], link(r), r["fed_by"])] for r in rs],
                         columns=["claim", "quantity", "paper", "ours", "unit", "status", "explained in", "fed by"])
        out += [t.to_markdown(index=False, tablefmt="github", disable_numparse=True), ""]
    return "\n".join(out)


def write(rows: list[dict], csv_out, md_out, html_out=None) -> None:
    with open(csv_out, "w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS, lineterminator="\n", extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    Path(md_out).write_text(markdown(rows) + "\n")
    if html_out:
        rows = sorted(rows, key=lambda r: section_key(r["section"]))
        # each claim links to its audit: what `esnap audit CLAIM_ID` prints, less the disk check
        audits = [(f"{AUDIT}{r['claim_id']}", r["claim_id"],
                   "\n".join(numbers.claim_head(r) + numbers.format_lineage(r["_lineage"]))) for r in rows]
        Path(html_out).write_text(html.table("Claims ledger", count_line(rows) + ". Each claim id links to its audit.",
                                             COLUMNS, rows, lambda r: "differs" if r["status"] == DIFFERS else "",
                                             anchor=("claim_id", AUDIT), sections=audits))


def read(path="results/tables/claims.csv") -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))
