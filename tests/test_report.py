"""The paper's build products on the session's smoke run (conftest.smoke_run): Fig. 1, Table I
from the lineage (a leak reads "not proved"), the claims ledger, the HTML report opened in headless
Chromium (a broken PNG fails it) and the RO-Crate (a result changed after it was written fails it).
Every test that changes a file of the run restores it."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import pandas as pd
import pytest

from embodied_snap.lineage.audit import audit
from embodied_snap.lineage.checks import check
from embodied_snap.paper import crate, table1

from test_workflow import BIN, run, sealed_group_in_train, snakemake

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def wf(smoke_run):
    return smoke_run


def test_fig1_and_the_tables_are_built(wf):
    assert {"fig1_system.png", "fig1_system.pdf"} <= {p.name for p in (wf / "results/figures").iterdir()}
    # panel (a) is the simulated rig's render, (b) one recorded strike
    reads = json.loads((wf / "results/provenance/fig_system/_.json").read_text())["reads"]
    assert "results/twin/render.png" in reads
    assert len({r.split("/")[2] for r in reads if r.startswith("raw_data/groups/")}) == 1
    rows = list(csv.DictReader(open(wf / "results/tables/table1_evidence.csv")))
    by = {r["evidence"]: r for r in rows}
    index = pd.read_csv(wf / "raw_data/index.csv")
    for es, n in index.evidence_set.value_counts().items():
        assert int(by[es if es != "dynamics" else "dynamics corpus"]["n"]) == n
    assert all(r["verdict"] == "proved (DAG and records)" for r in rows)
    assert "characterize_servo" in by["servo_calibration"]["use"]
    for ext in ("md", "tex", "html"):
        assert (wf / f"results/tables/table1_evidence.{ext}").stat().st_size > 0
    # the ledger holds every stage's claims, and its count line is the first line after the title
    ledger = list(csv.DictReader(open(wf / "results/tables/claims.csv")))
    stages = {p.parent.name for p in (wf / "results").glob("*/claims.csv") if p.parent.name != "tables"}
    assert {r["stage"] for r in ledger} == stages
    n = sum(1 for s in stages for _ in csv.DictReader(open(wf / f"results/{s}/claims.csv")))
    assert len(ledger) == n
    assert all(r["fed_by"] and r["artifact"] for r in ledger)
    assert all(r["explained_in"] for r in ledger if r["status"] == "differs")
    top = (wf / "results/tables/claims.md").read_text().splitlines()[2]
    assert top.startswith(f"{sum(r['status'] != 'no paper value' for r in ledger)} paper numbers, ")
    out = run([str(BIN / "esnap"), "claims", "--section", "III-A", "--status", "agrees"], wf).stdout
    lines = out.splitlines()[1:]
    assert lines and all(ln.startswith("III-A") and ln.endswith("agrees") for ln in lines)


def test_table1_says_not_proved_when_a_leak_is_injected(wf):
    with sealed_group_in_train(wf) as sealed:
        res = check(wf, static=False)
        rows = {r["evidence"]: r for r in table1.rows(res, wf)}
    assert not res["ok"]
    assert rows["dynamics sealed"]["verdict"].startswith("not proved") and sealed in rows["dynamics sealed"]["verdict"]
    assert rows["servo_calibration"]["verdict"] == "proved (records)"


def _report(wf):
    snakemake(wf, "--report", "results/report.html")
    return wf / "results/report.html"


def _browser():
    pytest.importorskip("playwright")
    from embodied_snap.paper.browser import CHROMIUM

    if not Path(CHROMIUM).exists():
        if os.environ.get("CI"):
            pytest.fail(f"{CHROMIUM} missing: install Debian's chromium (apt-get install chromium)")
        pytest.skip(f"{CHROMIUM} missing")
    from embodied_snap.paper.browser import check_report

    return check_report


def test_report_opens_in_chromium_with_every_figure_and_table(wf):
    check_report = _browser()
    html = _report(wf)
    res = check_report(html, wf / "results/report.png", show="results/figs/fig1_system.png")
    assert res["problems"] == []
    figs = {f"results/figs/{p.name}" for p in (wf / "results/figures").glob("*.png")}
    # the later targets' figures and tables join the report once they exist (the crate waits on them:
    # docs/report.md)
    figs |= {f for f in ["results/figs/figS1_robustness.png", "results/figs/figS2_sensitivity.png"]
             if (wf / f).exists()}
    tables = {f"results/tables/{p.name}" for p in (wf / "results/tables").glob("*.html")}
    tables |= {f for f in ["results/sensitivity/starts.html", "results/landscape/architectures.html"]
               if (wf / f).exists()}
    assert {"results/tables/table1_evidence.html", "results/tables/claims.html"} <= tables
    assert set(res["results"]) == figs | tables
    assert all(v.startswith(("image", "table")) for v in res["results"].values())
    n = len((wf / "results/tables/claims.csv").read_text().splitlines()) - 1
    # each number of the ledger links to its audit, and the browser followed one (issue 28)
    assert res["results"]["results/tables/claims.html"] == f"table of {n} rows, {n} links to their sections"
    assert (wf / "results/report.png").stat().st_size > 10_000
    # captions carry the ledger's numbers and the lineage
    text = html.read_text()
    assert "Ledger, section" in text and "esnap audit results/figs/fig2_limits.png" in text


def test_report_check_fails_on_a_broken_png(wf):
    check_report = _browser()
    f = wf / "results/figs/fig2_limits.png"
    good, st = f.read_bytes(), f.stat()
    f.write_bytes(good[:8] + b"not an image" * 20)  # a PNG's signature and nothing of one
    try:
        res = check_report(_report(wf), only=["results/figs/fig2_limits.png"])
    finally:
        f.write_bytes(good)
        os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert res["problems"] == ["results/figs/fig2_limits.png: the image does not load (naturalWidth 0)"]


def test_report_check_fails_on_a_claim_linked_to_no_audit(wf):
    check_report = _browser()
    f = wf / "results/tables/claims.html"
    good, st = f.read_text(), f.stat()
    f.write_text(good.replace('<section id="audit-tendon_travel_per_tick_um">', "<section>"))
    try:
        res = check_report(_report(wf), only=["results/tables/claims.html"])
    finally:
        f.write_text(good)
        os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns))
    n = len((wf / "results/tables/claims.csv").read_text().splitlines()) - 1
    assert res["problems"] == [f"results/tables/claims.html: 1 of {n} links lead nowhere, "
                               "first #audit-tendon_travel_per_tick_um"]


def test_crate_lists_every_result_and_reaches_every_raw_group_of_a_figure(wf):
    from rocrate.rocrate import ROCrate

    assert crate.verify(wf) == []
    c = ROCrate(wf / "results/crate")
    assert c.mainEntity.id == "Snakefile"
    for fig in sorted((wf / "results/figures").glob("*.png")):
        p = fig.relative_to(wf).as_posix()
        fed = {g for s in audit(p, wf)["evidence_sets"].values() for g in s["fed"]}
        reached = {q.split("/")[2] for q in crate.upstream(wf, path=p) if q.startswith("raw_data/groups/")}
        assert fed and fed <= reached, p


def test_crate_check_fails_when_a_result_changes_after_it_was_written(wf):
    f = wf / "results/tables/claims.md"
    good, st = f.read_bytes(), f.stat()
    f.write_bytes(good + b"\nedited\n")
    try:
        bad = crate.verify(wf)
        r = run([str(BIN / "esnap"), "crate", "--verify"], wf, check=False)
    finally:
        f.write_bytes(good)
        os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert bad == ["results/tables/claims.md: sha256 differs from the crate's (rule: the crate describes the "
                   "results as they are)"]
    assert r.returncode == 1 and "claims.md" in r.stdout
    assert json.loads((wf / "results/crate/ro-crate-metadata.json").read_text())["@graph"]
