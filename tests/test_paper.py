"""The paper's build products on hand-built inputs: agreement rules of the claims ledger, Table I's
verdicts (a leak reads "not proved"), the report's sections, the RO-Crate read back."""

import json

import pytest

from embodied_snap.lineage import policy as P
from embodied_snap.lineage import records as pv
from embodied_snap.lineage.checks import by_source
from embodied_snap.paper import crate, ledger, table1
from embodied_snap.paper.sections import category, section_of

from lineage_tree import group_files as _group
from lineage_tree import write as _write


@pytest.mark.parametrize("paper,ours,ok", [
    ("15.8", "16.09", True), ("15.8", "18", False),            # point, within / beyond 10 %
    ("[14.4, 18]", "[15.91, 16.66]", True),                    # intervals overlap
    ("[22.3, 23.1]", "[15.79, 16.72]", False),
    ("[1.56, 1.64]", "1.6", True), ("[1.56, 1.64]", "1.4", False),
    ("21", "[12.78, 14]", False), ("21", "[19, 20]", True),    # point vs our range (seeds)
    ("[16, 38, 86]", "[16.94, 26.14, 38.91]", False),          # per section
    ("[16, 38, 86]", "[17, 37, 80]", True),
    ("[0.45, 0.75]", "[0.7, 0.7, 0.55]", True),                # interval vs values per seed
    ("<1e-10", "0.09", False), ("<1e-10", "1e-12", True),
    ("0", "0", True), ("0", "0.1667", False),
    ("", "0.5", None), ("5", "", None),
    ("none", "none", True), ("none", "0.5", False),            # a word (Table II: online correction)
    ("none", "no complete trial", False),
    ("[1.19, 1.44]", "[, ]", None),                            # an empty range is not measured
])
def test_agreement_rules(paper, ours, ok):
    assert ledger.agrees(ledger.parse(paper), ledger.parse(ours), 0.10) is ok


def test_sections_of_captions():
    assert section_of("text (paper section III-A/B).") == ["III-A", "III-B"]
    assert section_of("(paper sections V-A, V-B)") == ["V-A", "V-B"]
    assert category("(paper section IV-A)") == "Section IV-A"
    assert category("no section") == "Data and evidence (Table I)"


def _sep(violations=(), static=True):
    """A separation proof as lineage.checks.check returns it."""
    per, rest = by_source(list(violations))
    return dict(ok=not violations, violations=list(violations), raw_dir="raw_data",
                checked=dict(target_sizes={"results/policy/targets_evaluation.parquet": 16}),
                sources={k: dict(rule=s.rule, uses=["x"], violations=per.get(k, []), ok=not per.get(k) and not rest,
                                 dag=static, records=True) for k, s in P.POLICY.items()},
                unattributed=rest)


def _index(root):
    rows = [("cal_0001", "servo_calibration", "burst"), ("dyn_0001", "dynamics", "free_space"),
            ("dyn_0002", "dynamics", "sealed"), ("dyn_0003", "dynamics", "pilot")]
    _write(root, "raw_data/index.csv", ("group_id,evidence_set,category,session\n" + "".join(
        f"{g},{e},{c},s01\n" for g, e, c in rows)).encode())
    _write(root, "results/splits/split.csv",
           b"group_id,role\ndyn_0001,train\ndyn_0002,sealed\ndyn_0003,validation\n")


def test_table1_rows_counts_and_verdicts(tmp_path):
    _index(tmp_path)
    rows = {r["evidence"]: r for r in table1.rows(_sep(), tmp_path)}
    assert rows["servo_calibration"]["n"] == 1 and rows["servo_calibration"]["domain"] == "rig (simulated)"
    assert rows["dynamics corpus"]["n"] == 3
    assert rows["dynamics corpus"]["separation"] == "group split: 1 train, 1 validation, 1 sealed"
    assert rows["dynamics sealed"]["n"] == 1 and rows["evaluation targets"]["n"] == 16
    assert all(r["verdict"] == "proved (DAG and records)" for r in rows.values())
    assert table1.rows(_sep(), tmp_path, simulated=False)[0]["domain"] == "rig recordings"
    # a variant's target set is named by its folder; the deployment trials by their own index
    assert table1.target_name("results/robustness/uniform/targets_training.parquet") == "uniform training targets"
    assert table1.target_name("results/policy/targets_evaluation.parquet") == "evaluation targets"
    _write(tmp_path, "raw_data/deployment/index.csv", b"group_id\ndep_0001\ndep_0002\n")
    rows = {r["evidence"]: r for r in table1.rows(_sep(), tmp_path)}
    assert rows["deployment"]["n"] == 2


def test_table1_says_not_proved_when_a_leak_is_injected(tmp_path):
    _index(tmp_path)
    leak = (f"separation (split): results/splits/split.csv puts sealed group dyn_0002 in train; "
            f"docs/design.md 3: {P.POLICY['sealed'].rule}")
    rows = {r["evidence"]: r for r in table1.rows(_sep([leak]), tmp_path)}
    assert rows["dynamics sealed"]["verdict"].startswith("not proved: 1 violation(s)")
    assert rows["dynamics corpus"]["verdict"].startswith("not proved")
    assert rows["servo_calibration"]["verdict"].startswith("proved")
    # a violation no source owns (an unreadable record) leaves no row proved
    rows = table1.rows(_sep(["separation (records): results/provenance/x/_.json cannot be read"]), tmp_path)
    assert all(r["verdict"].startswith("not proved") for r in rows)
    written = table1.write(rows, tmp_path / "t1")
    assert [p.suffix for p in written] == [".csv", ".md", ".tex", ".html"]
    assert "not proved" in (tmp_path / "t1.md").read_text() and "\\toprule" in (tmp_path / "t1.tex").read_text()


def _run(root):
    """raw group -> a stage fit -> its claims table, and a figure of the fit."""
    _index(root)
    files = _group(root, "cal_0001")
    _write(root, "reference/paper_values.yaml", b"{}")
    fit = _write(root, "results/characterize/servo.json", b"{}")
    pv.write_record("characterize_servo", {}, files, [fit], {}, "t", root=root)
    claims = _write(root, "results/characterize/claims.csv", (
        "claim_id,section,quantity,paper,ours,unit,source\n"
        "a,III-A,first,15.8,16.09,um,results/characterize/servo.json:a\n"
        "b,III-A,second,\"[1, 2]\",3,-,results/characterize/servo.json:b\n"
        "c,III-B,third,,4,-,results/characterize/servo.json:c\n").encode())
    pv.write_record("table_characterize_claims", {}, [fit, "reference/paper_values.yaml"], [claims], {}, "t",
                    root=root, reads=[fit])
    fig = _write(root, "results/figs/fig2_limits.png", b"png")
    pv.write_record("fig_limits", {}, [fit], [fig], {}, "t", root=root)
    return claims, fig, files


def test_ledger_rows_artifact_fed_by_and_doc(tmp_path):
    claims, _, _ = _run(tmp_path)
    _write(tmp_path, "docs/characterize.md", b"# why b differs")
    rows = {r["claim_id"]: r for r in ledger.ledger([claims], tmp_path)}
    assert rows["a"]["status"] == "agrees" and rows["b"]["status"] == "differs"
    assert rows["c"]["status"] == "no paper value"
    assert rows["a"]["artifact"] == "results/characterize/servo.json"
    assert rows["a"]["fed_by"] == "servo_calibration 1/1"
    assert rows["b"]["explained_in"] == "docs/characterize.md" and rows["a"]["explained_in"] == ""
    md = ledger.markdown(list(rows.values()))
    assert md.splitlines()[2].startswith("2 paper numbers, 1 reproduced within tolerance, 0 agree by construction")
    assert md.index("## III-A") < md.index("## III-B")


def test_a_claim_the_rig_took_from_the_paper_agrees_by_construction_only_on_the_rig(tmp_path, monkeypatch):
    claims, _, _ = _run(tmp_path)
    monkeypatch.setattr(ledger, "by_construction", lambda stage, cid: "the rig's input" if cid in "ab" else None)
    rows = {r["claim_id"]: r for r in ledger.ledger([claims], tmp_path)}
    assert rows["a"]["status"] == "by construction" and rows["a"]["explained_in"] == "docs/twin.md"
    assert rows["b"]["status"] == "differs"  # a difference stays one
    assert ledger.count_line(list(rows.values())).startswith("2 paper numbers, 0 reproduced within tolerance, "
                                                              "1 agree by construction")
    rows = {r["claim_id"]: r for r in ledger.ledger([claims], tmp_path, simulated=False)}
    assert rows["a"]["status"] == "agrees"  # a real rig's recordings: judged like any other


def test_every_by_construction_claim_is_a_paper_claim_with_its_reason():
    from embodied_snap.reference import paper_values

    ref = paper_values()
    built = {(st, cid): c["by_construction"] for st, cs in ref.items() if isinstance(cs, dict)
             for cid, c in cs.items() if isinstance(c, dict) and "by_construction" in c}
    assert built, "the simulated rig's operating point is a paper result: at least its claims are built in"
    for (st, cid), why in built.items():
        assert ref[st][cid].get("paper") is not None and len(why) > 20, (st, cid)


def test_crate_lists_every_result_once_and_fails_when_one_changes(tmp_path):
    from rocrate.rocrate import ROCrate

    _, fig, files = _run(tmp_path)
    _write(tmp_path, "Snakefile", b"# wf")
    crate.write(tmp_path)
    assert crate.verify(tmp_path) == []
    c = ROCrate(tmp_path / "results/crate")
    assert c.mainEntity.id == "Snakefile"
    jobs = [e for e in c.get_entities() if e.type == "CreateAction" and e.id.startswith("#job-")]
    assert len(jobs) == 3 and all(e["instrument"].type == "SoftwareApplication" for e in jobs)
    meta = json.loads((tmp_path / "results/crate/ro-crate-metadata.json").read_text())
    assert {e["name"] for e in meta["@graph"] if e.get("@type") == "HowToStep"} == {
        "characterize_servo", "fig_limits", "table_characterize_claims"}
    # the figure's raw group is reachable from the figure through the actions
    assert set(files) <= crate.upstream(tmp_path, path=fig)
    (tmp_path / fig).write_bytes(b"another png")
    bad = crate.verify(tmp_path)
    assert len(bad) == 1 and bad[0].startswith(f"{fig}: sha256 differs")


def test_a_deployment_with_every_trial_aborted_still_gives_a_ledger_row_per_claim():
    """Under heavy load the real-time trials can all fail the gate: the claims say so, the ledger
    parses them (not measured, or a differing word), and the run goes on to its report."""
    from embodied_snap.deploy import table2 as D
    s = D.summarize(D.pd.DataFrame(), 3, 3, 110.0, 1.0, aborted=3)
    man = {"placements": [{"distance_m": 0.62, "bearing_deg": 0.0}, {"distance_m": 0.69, "bearing_deg": 91.0}]}
    rows = D.claims(s, man)
    assert rows and all(ledger.agrees(ledger.parse(r["paper"]), ledger.parse(r["ours"]), 0.1) is not True
                        for r in rows if r["claim_id"] in ("peak_speed_iqr_mps", "online_correction"))
