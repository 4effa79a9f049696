"""`esnap validate --partial`: a tree holding part of the corpus (one session's evidence set) goes
through the same gate, without the split and its size rule; the output names the sets present and
missing, and what needs each missing one (lineage.policy.needs, held to the rules' inputs here)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest

from embodied_snap import budget, sealed
from embodied_snap.cli import main
from embodied_snap.io import write_json
from embodied_snap.lineage.policy import needs
from embodied_snap.plan import load_plan
from embodied_snap.rawformat import EVIDENCE, group_paths, read_meta, write_index
from embodied_snap.validate import RecordingError, validate_group

from fakerig import write_fake_group
from paper_protocol import LIMITS

REPO = Path(__file__).resolve().parent.parent
OTHERS = ("servo_calibration", "attachment", "release_mode", "delay_sweep", "dynamics")
HELD = ("hb_0001", "hb_0002", "hb_0003", "hb_0004")  # exactly the smoke budget's held-base ids


def tree(raw: Path, groups) -> Path:
    """groups: (id, evidence_set, category); valid rig-format groups with the labels and target
    their set needs, and their index.csv."""
    rows = []
    for i, (gid, es, cat) in enumerate(groups):
        rows.append(write_fake_group(raw, gid, es, cat, session=f"s{i % 2 + 1:02d}", duration_s=3.0, seed=i))
        path = group_paths(raw, gid)["meta"]
        meta = read_meta(path)
        if es == "held_base":
            meta["labels"]["base_event_t"] = meta["labels"]["t_s1"]
        if cat in ("sealed", "target"):
            meta["target"] = {"position": [0.45, 1.05, 0.10]}
        write_json(meta, path)
    write_index(rows, raw / "index.csv")
    return raw


def files(raw: Path) -> dict[str, int]:
    return {str(p.relative_to(raw)): p.stat().st_mtime_ns for p in sorted(raw.rglob("*"))}


def validate(capsys, monkeypatch, raw, *args):
    monkeypatch.chdir(REPO)  # config.yaml: the paper budget (78 validation groups)
    rc = main(["validate", str(raw), "--source", "rig", *args])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture
def held(tmp_path):
    return tree(tmp_path / "raw_data", [(g, "held_base", "held") for g in HELD])


def test_a_held_base_session_passes_and_names_what_is_missing(held, capsys, monkeypatch):
    before = files(held)
    rc, out, err = validate(capsys, monkeypatch, held, "--partial")
    assert (rc, err) == (0, ""), err
    assert out.startswith("4 groups valid (partial corpus: held_base 4); missing: servo_calibration (needed by ")
    assert out.count("\n") == 1
    for es in OTHERS:
        assert f"{es} (needed by " in out
    assert "held_base (" not in out.split("missing:")[1]
    assert "characterize_kinematics" in out and "characterize_servo" in out  # servo_calibration's fits
    # the dynamics corpus's, a stage as one entry counting the policy's rules of that stage
    from embodied_snap.lineage.policy import needs

    for stage in ("policy", "dynamics"):
        n = sum(r.startswith(f"{stage}_") for r in needs("dynamics"))
        assert n > 4 and f"{stage}_* ({n})" in out, out
    assert files(held) == before  # nothing written: no sealed.json, no cache


def test_without_partial_the_split_size_rule_still_applies(held, capsys, monkeypatch):
    rc, out, err = validate(capsys, monkeypatch, held)
    assert (rc, out) == (1, "")
    assert err == "error: split: 78 validation groups asked of 0 (rule: split sizes)\n"


def test_a_bad_group_in_a_partial_tree_is_refused_by_the_gate(held, capsys, monkeypatch):
    path = group_paths(held, "hb_0003")["meta"]
    meta = read_meta(path)
    del meta["labels"]["base_event_t"]
    write_json(meta, path)
    row = pd.read_csv(held / "index.csv").set_index("group_id").loc["hb_0003"]
    with pytest.raises(RecordingError) as e:  # the gate's own line for this group
        validate_group(held, "hb_0003", {"group_id": "hb_0003", **row.to_dict()}, limits=LIMITS)
    rc, out, err = validate(capsys, monkeypatch, held, "--partial")
    assert (rc, out) == (1, "")
    assert err == f"error: {e.value}\n" and "rule: labels complete per evidence set" in err


DYN = [("dyn_0001", "dynamics", "free_space"), ("dyn_0002", "dynamics", "free_space"),
       ("dyn_0003", "dynamics", "target"), ("dyn_0004", "dynamics", "sealed"), ("dyn_0005", "dynamics", "sealed")]


def test_some_dynamics_groups_pass_partial(tmp_path, capsys, monkeypatch):
    raw = tree(tmp_path / "raw_data", DYN[:4])
    rc, out, err = validate(capsys, monkeypatch, raw, "--partial")
    assert (rc, err) == (0, ""), err
    assert out.startswith("4 groups valid (partial corpus: dynamics 4); missing: ")
    assert [es for es in EVIDENCE if f"{es} (needed by " in out] == [es for es in OTHERS if es != "dynamics"] + [
        "held_base"]
    assert not (raw / sealed.RECORD).exists()


def test_the_sealed_groups_a_partial_tree_holds_are_checked_against_the_record(tmp_path, capsys, monkeypatch):
    full = tree(tmp_path / "full", DYN)
    monkeypatch.chdir(REPO)
    cfg = {**__import__("yaml").safe_load((REPO / "config.yaml").read_text())}
    cfg["raw_data"] = {**cfg["raw_data"], "source": "rig", "dir": str(full)}
    sealed.seal(full, load_plan(cfg, full, partial=True), "test")  # dyn_0004 and dyn_0005
    raw = tree(tmp_path / "raw_data", DYN[:4])  # dyn_0005 not recorded yet: not asked for
    (raw / sealed.RECORD).write_bytes((full / sealed.RECORD).read_bytes())
    rc, out, err = validate(capsys, monkeypatch, raw, "--partial")
    assert (rc, err) == (0, ""), err
    rec = json.loads((raw / sealed.RECORD).read_text())
    assert sorted(rec["groups"]) == ["dyn_0004", "dyn_0005"]  # untouched

    # ... but one it holds that disagrees with the record is refused, as always
    index = pd.read_csv(raw / "index.csv")
    index.loc[index.group_id == "dyn_0004", "category"] = "free_space"
    index.to_csv(raw / "index.csv", index=False)
    path = group_paths(raw, "dyn_0004")["meta"]
    write_json({**read_meta(path), "category": "free_space"}, path)
    rc, out, err = validate(capsys, monkeypatch, raw, "--partial")
    assert (rc, out) == (1, "")
    assert re.fullmatch(r"error: \S+sealed\.json: group dyn_0004: sealed group is now free_space \(dynamics\), "
                        r"was sealed \(sealed\) \(rule: sealed set is fixed.*\)\n", err), err


def test_a_partial_lab_tree_is_no_budgets(held):
    """budget.check_tree names a tree by its index.csv listing exactly a budget's simulated groups:
    a lab's held-base session with the smoke budget's held-base ids is not the smoke budget's."""
    cfg = __import__("yaml").safe_load((REPO / "config.yaml").read_text())
    for name in cfg["budgets"]:
        budget.check_tree({**cfg, "budget": name}, held, argv=["esnap", "validate"])


# --- needs() against the workflow: every rule whose input reads a set's recordings needs it ------------

RULE = re.compile(r"^(?:rule|checkpoint) (\w+):\n((?:[ \t]+.*\n|\n)*)", re.M)


def _reads() -> dict[str, set[str]]:
    """Evidence set -> the rules whose inputs call raw_of for it (rules/*.smk, read as text)."""
    text = "\n".join(p.read_text() for p in sorted((REPO / "rules").glob("*.smk")))
    names = {m[1]: m[2] for m in re.finditer(r"^(\w+) = (dict\(.*\)|\[.*\])$", text, re.M)}
    out: dict[str, set[str]] = {}
    for rule, body in RULE.findall(text):
        for arg in re.findall(r"raw_of\(([^)]*)\)", body):
            arg = names.get(arg.removeprefix("**"), arg)
            m = re.search(r"evidence_set=(\"\w+\"|\w+)", arg)
            if m:
                sets = eval(names.get(m[1], m[1]))  # noqa: S307 -- the rule files' own literals
            elif re.search(r"role=\"(train|validation|sealed)\"", arg):
                sets = "dynamics"
            elif "FIG1_GROUP" in arg:
                sets = "attachment"  # FIG1_GROUP: the first attachment trial (rules/common.smk)
            else:
                continue  # raw_of(): every group, bookkeeping (the separation proof)
            for es in [sets] if isinstance(sets, str) else sets:
                out.setdefault(es, set()).add(rule)
    return out


def test_needs_covers_every_rule_reading_a_set():
    reads = _reads()
    assert set(reads) == {"servo_calibration", "attachment", "release_mode", "delay_sweep", "dynamics", "held_base"}
    bookkeeping = {"validate_sealed", "check_separation"}
    for es, rules in reads.items():
        assert rules - bookkeeping <= set(needs(es)), (es, rules - bookkeeping - set(needs(es)))
