"""The commands that read a finished run: `audit`, `check-separation` and `prov` (its lineage),
`claims` (the ledger), `crate` (the RO-Crate of its results), `report-check` (the HTML report)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from .common import UsageError, config_args, existing_dir, existing_file, given_path, load_config


def add_audit(sub) -> None:
    au = sub.add_parser("audit", help="which recordings fed RESULT (a file, a claim id or FILE:KEY), which never "
                                      "did, and whether it is stale")
    au.add_argument("result", metavar="RESULT", help="a file or directory of the run, a claim id of the ledger "
                    "(tendon_travel_per_tick_um), or FILE:KEY (results/characterize/servo.json:rate_tick_s)")
    au.add_argument("--root", default=".")
    au.add_argument("--json", action="store_true")
    config_args(au, "default: the config the last run recorded")
    au.set_defaults(fn=cmd_audit)


def add_check_separation(sub) -> None:
    cs = sub.add_parser("check-separation", help="prove the evidence-set separation (docs/design.md section 3)")
    config_args(cs, "default: the config the last run recorded")
    cs.add_argument("--root", default=".")
    cs.add_argument("--no-static", action="store_true", help="skip the Snakemake DAG check")
    cs.add_argument("--no-records", action="store_true", help="skip the provenance-record check")
    cs.set_defaults(fn=cmd_check_separation)


def add_prov(sub) -> None:
    pr = sub.add_parser("prov", help="export the run's provenance as W3C PROV-JSON")
    pr.add_argument("--root", default=".")
    pr.add_argument("--out", default="results/lineage/prov.json")
    pr.set_defaults(fn=cmd_prov)


def add_claims(sub) -> None:
    cl = sub.add_parser("claims", help="the claims ledger: every paper number beside ours, by section and status")
    cl.add_argument("--section", action="append", help="only this paper section, e.g. III-B (repeatable)")
    cl.add_argument("--status", action="append", help="only claims with this status, e.g. differs (repeatable)")
    cl.add_argument("--root", default=".")
    cl.add_argument("--ledger", default="results/tables/claims.csv")
    cl.set_defaults(fn=cmd_claims)


def add_crate(sub) -> None:
    cr = sub.add_parser("crate", help="write the run as a Workflow Run RO-Crate (or --verify it against results/)")
    cr.add_argument("--out", default="results/crate/")
    cr.add_argument("--root", default=".")
    cr.add_argument("--verify", action="store_true", help="check that every result file is in it with its sha256")
    cr.set_defaults(fn=cmd_crate)


def add_report_check(sub) -> None:
    rc = sub.add_parser("report-check", help="open the HTML report in headless Chromium: every figure and table shown")
    rc.add_argument("html", nargs="?", default="results/report.html")
    rc.add_argument("--screenshot", default="results/report.png")
    rc.set_defaults(fn=cmd_report_check)


def _run_config(a) -> dict | None:
    """The config named on the command line (--configfile, --config), None when neither is given
    (then: the config the last run recorded)."""
    from .. import runconfig

    return load_config(a, root=a.root) if runconfig.given(a) else None


def _fits_run(a, cfg: dict | None) -> None:
    """A config asking for another budget than the one results/ holds: one line, before any record is read."""
    from .. import budget

    if cfg is not None:
        try:
            budget.fits(cfg, a.root, argv=a.argv)
        except budget.BudgetError as e:
            raise UsageError(str(e)) from None


def cmd_audit(a) -> int:
    from ..lineage.audit import audit, format_audit

    existing_dir(a.root, "--root")
    cfg = _run_config(a)
    _fits_run(a, cfg)
    if not (Path(a.root) / given_path(a.result, "RESULT")).exists():
        if ":" not in a.result and "/" in a.result:
            raise UsageError(f"{a.result}: no such file or directory under {a.root}")
        return _audit_number(a)  # CLAIM_ID or FILE:KEY
    report = audit(a.result, root=a.root, config=cfg)
    print(json.dumps(report, indent=1, default=str) if a.json else format_audit(report))
    return 1 if report.get("stale") else 0


def _audit_number(a) -> int:
    from ..lineage.numbers import NumberError, audit_number, format_number

    try:
        r = audit_number(a.result, root=a.root)
    except NumberError as e:
        raise UsageError(str(e)) from None
    print(json.dumps(r, indent=1, default=str) if a.json else format_number(r))
    return 1 if r["stale"] else 0


def cmd_check_separation(a) -> int:
    from ..lineage.checks import check

    existing_dir(a.root, "--root")
    cfg = _run_config(a)
    _fits_run(a, cfg)
    res = check(a.root, static=not a.no_static, records=not a.no_records, config_overrides=cfg)
    for v in res["violations"]:
        print(f"leak: {v}")
    print("separation holds" if res["ok"] else f"{len(res['violations'])} separation violation(s)")
    return 0 if res["ok"] else 1


def cmd_prov(a) -> int:
    from ..lineage.prov import export

    existing_dir(a.root, "--root")
    given_path(a.out, "--out")
    try:
        print(export(a.root, a.out))
    except OSError as e:
        raise UsageError(f"--out {a.out}: cannot write it ({e.strerror or e})") from None
    return 0


def cmd_claims(a) -> int:
    """The claims ledger, filtered by paper section and status."""
    from ..paper.ledger import COLUMNS, STATUSES, count_line, read
    from ..paper.sections import section_key

    for s in a.status or []:
        if s not in STATUSES:
            raise UsageError(f"--status {s}: no such claim status (statuses: {', '.join(STATUSES)})")
    path = Path(existing_dir(a.root, "--root")) / a.ledger
    if not path.is_file():
        print(f"error: {a.ledger}: no claims ledger (run: snakemake results/tables/claims.csv)", file=sys.stderr)
        return 1
    try:
        rows = read(path)
    except (OSError, UnicodeDecodeError) as e:
        print(f"error: {a.ledger}: cannot read the claims ledger ({e})", file=sys.stderr)
        return 1
    lacks = sorted(set(COLUMNS) - set(rows[0])) if rows else []
    if lacks:
        print(f"error: {a.ledger}: not a claims ledger (no column {', '.join(lacks)})", file=sys.stderr)
        return 1
    sections = sorted({r["section"] for r in rows}, key=section_key)
    for s in a.section or []:
        if s not in sections:
            raise UsageError(f"--section {s}: no such section in {a.ledger} "
                             f"(sections: {', '.join(sections) or 'none'})")
    rows = [r for r in rows if (not a.section or r["section"] in a.section)
            and (not a.status or r["status"] in a.status)]
    print(count_line(rows))
    w = max([len(r["claim_id"]) for r in rows] + [8])
    for r in rows:
        doc = f"  -> {r['explained_in']}" if r["explained_in"] else ""
        print(f"{r['section']:<8} {r['claim_id']:<{w}} paper {r['paper'] or '-':<16} ours {r['ours'] or '-':<20} "
              f"{r['unit']:<10} {r['status']}{doc}")
    return 0


def cmd_crate(a) -> int:
    from ..paper.crate import verify, write

    existing_dir(a.root, "--root")
    if a.verify:
        meta = Path(a.root) / a.out / "ro-crate-metadata.json"
        if not meta.is_file():
            print(f"error: {a.out}: no crate (no ro-crate-metadata.json; write it: esnap crate)", file=sys.stderr)
            return 1
        bad = verify(a.root, a.out.rstrip("/"))
        for b in bad:
            print(f"error: {b}")
        print("crate matches results/" if not bad else f"{len(bad)} result file(s) differ from the crate")
        return 1 if bad else 0
    given_path(a.out, "--out")
    try:
        print(write(a.root, a.out.rstrip("/")))
    except OSError as e:
        raise UsageError(f"--out {a.out}: cannot write the crate there ({e.strerror or e})") from None
    return 0


def cmd_report_check(a) -> int:
    existing_file(a.html, "report")
    given_path(a.screenshot, "--screenshot")
    try:
        from playwright.sync_api import Error as PlaywrightError
    except ImportError:
        print("error: report-check needs playwright (pip install -e '.[dev]')", file=sys.stderr)
        return 1

    from ..paper.browser import check_report

    try:
        res = check_report(a.html, a.screenshot)
    except PlaywrightError as e:
        print(f"error: headless Chromium: {str(e).splitlines()[0]}", file=sys.stderr)
        return 1
    for path, what in res["results"].items():
        print(f"{path}: {what}")
    for prob in res["problems"]:
        print(f"error: {prob}")
    print("report ok" if not res["problems"] else f"{len(res['problems'])} problem(s)")
    return 1 if res["problems"] else 0
