"""`esnap lab plan` writes the acquisition protocol's groups in the order an operator works, and
`esnap lab acquire` refuses, in one line and before any port opens, every argument or plan that
could move the arm differently from the plan (embodied_snap/lab; docs/lab.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from embodied_snap.cli import main
from embodied_snap.lab import acquire as LA
from embodied_snap.lab import plan as LP
from embodied_snap.plan import twin_plan
from embodied_snap.rawformat import EVIDENCE_SETS

REPO = Path(__file__).resolve().parent.parent
CONFIG = yaml.safe_load((REPO / "config.yaml").read_text())


@pytest.fixture(scope="module")
def smoke_plan(tmp_path_factory):
    doc = LP.build(CONFIG, "smoke")
    path = tmp_path_factory.mktemp("plan") / "plan.yaml"
    LP.write(doc, path)
    return doc, path


pytestmark = pytest.mark.usefixtures("no_port")  # conftest: opening a port fails the test


def test_the_plan_holds_the_budgets_groups_one_session_and_set_at_a_time(smoke_plan):
    doc, _ = smoke_plan
    want = twin_plan(CONFIG["budgets"]["smoke"]["groups"], CONFIG["sessions"])
    assert sorted(e["group_id"] for e in doc["groups"]) == sorted(want.group_id)
    keys = [(e["session"], EVIDENCE_SETS.index(e["evidence_set"])) for e in doc["groups"]]
    assert keys == sorted(keys)  # sessions in turn, one evidence set at a time within each


def test_the_summary_times_each_set_from_its_programs(smoke_plan):
    # docs/lab.md's table of the sets' minutes is this summary at the paper budget
    doc, _ = smoke_plan
    lines = dict(ln.split(": ", 1) for ln in LP.summary(doc).splitlines())
    sets = {e["evidence_set"] for e in doc["groups"]}
    assert len(sets) == 6 and sets <= set(lines)
    for es in sets:
        g = [e for e in doc["groups"] if e["evidence_set"] == es]
        n, mins = lines[es].split(", ")[:2]
        assert n == f"{len(g)} groups" and mins.startswith(f"{sum(e['duration_s'] for e in g) / 60:.1f} min")
    assert "pushes the mount" in lines["held_base"] and lines["servo_calibration"].endswith("keeps clear")


def test_the_operator_is_asked_only_what_nothing_measures(smoke_plan):
    doc, _ = smoke_plan
    for e in doc["groups"]:
        need = CONFIG["gate"]["labels"].get(f"{e['evidence_set']}/{e['category']}",
                                            CONFIG["gate"]["labels"][e["evidence_set"]])
        assert set(e["labels"]) <= set(need)
        assert not set(e["labels"]) & (set(e["phases"]) | {"snap_speed_event"})
        assert ("base_event_t" in e["labels"]) is False  # the held-base cue is logged, never asked
        assert ("cue_s" in e) == (e["evidence_set"] == "held_base")
        assert ("target" in e) == ("attached" in need)
        assert ("attached" in e["labels"]) == ("attached" in need)


def test_every_goal_lies_inside_the_plans_envelope_and_is_drawn_again_the_same(smoke_plan):
    doc, path = smoke_plan
    doc = LP.load(path)
    lo, hi = (np.asarray(doc["envelope"][k]) for k in ("goal_min", "goal_max"))
    for e in doc["groups"]:
        g, times = LP.group_goals(doc, e)
        assert not g.flags.writeable and g.dtype == np.int64
        assert ((g >= lo) & (g <= hi)).all()
        assert {k: round(v, 4) for k, v in times.items()} == e["phases"]
        assert len(g) / doc["servos"]["hz"] == pytest.approx(e["duration_s"], abs=1e-3)


def test_an_edited_plan_is_refused(smoke_plan, tmp_path):
    _, path = smoke_plan
    text = path.read_text()
    edited = tmp_path / "edited.yaml"
    edited.write_text(text.replace("tau: 0.4909", "tau: 0.6", 1))
    assert edited.read_text() != text
    with pytest.raises(LP.PlanError, match=r"^.*edited.yaml: plan checksum mismatch"):
        LP.load(edited)


def test_a_plan_of_another_protocol_is_refused(smoke_plan, monkeypatch):
    _, path = smoke_plan
    monkeypatch.setattr(LP, "protocol_version", lambda: "0" * 12)
    with pytest.raises(LP.PlanError, match="write the plan again"):
        LP.load(path)


def test_changed_draws_are_caught_before_the_arm_moves(smoke_plan, monkeypatch, tmp_path):
    _, path = smoke_plan
    real = LP.drawn

    def drifted(row, seed, proto, hz):
        prog, off, g, times, cue = real(row, seed, proto, hz)
        g = g.copy()
        g[len(g) // 2] += 1
        return prog, off, g, times, cue

    monkeypatch.setattr(LP, "drawn", drifted)
    with pytest.raises(LA.LabError, match=r"group \w+: its goals drawn again differ from the plan's"):
        LA.checked(path, tmp_path / "session", None, None)


def lab(capsys, *argv):
    rc = main(["lab", *argv])
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].strip() and "Traceback" not in err[0], err
    return rc, err[0]


@pytest.mark.parametrize("args, rc, msg", [
    (["--from", "dyn_9999"], 2, r"--from dyn_9999: not a group of .*plan.yaml"),
    (["--baud", "9601"], 2, r"--baud 9601: not a baud rate of the XM430"),
    (["--baud", "4500000"], 2, r"--baud 4500000: .*dynamixel-sdk cannot set it"),
])
def test_acquire_refuses_a_bad_argument_in_one_line(capsys, smoke_plan, tmp_path, args, rc, msg):
    _, path = smoke_plan
    got, line = lab(capsys, "acquire", "--plan", str(path), "--port", "/dev/null", "--out", str(tmp_path / "s"),
                    "--yes", *args)
    assert got == rc
    assert __import__("re").search(msg, line), line


def test_acquire_refuses_a_port_that_is_not_there(capsys, smoke_plan, tmp_path):
    _, path = smoke_plan
    rc, line = lab(capsys, "acquire", "--plan", str(path), "--port", str(tmp_path / "ttyUSB7"), "--out",
                   str(tmp_path / "s"), "--yes")
    assert rc == 2 and "no such device" in line


def test_acquire_never_starts_at_a_recorded_group(capsys, smoke_plan, tmp_path):
    doc, path = smoke_plan
    gid = doc["groups"][3]["group_id"]
    d = tmp_path / "s" / "groups" / gid
    d.mkdir(parents=True)
    (d / "servo.parquet").write_bytes(b"recorded")
    (d / "meta.json").write_text("{}")
    rc, line = lab(capsys, "acquire", "--plan", str(path), "--port", "/dev/null", "--out", str(tmp_path / "s"),
                   "--yes", "--from", gid)
    assert rc == 2 and f"--from {gid}: already recorded" in line
    assert (d / "servo.parquet").read_bytes() == b"recorded"


def test_acquire_refuses_a_goal_outside_the_envelope(smoke_plan, tmp_path, monkeypatch):
    doc, _ = smoke_plan
    doc = dict(doc, envelope=dict(doc["envelope"], goal_max=[0.0] * 9))
    doc["checksum"] = LP.checksum(doc)
    path = tmp_path / "narrow.yaml"
    LP.write(doc, path)
    with pytest.raises(LA.LabError, match=r"command outside the envelope: servo \d goal"):
        LA.checked(path, tmp_path / "s", None, None)


def test_plan_refuses_to_overwrite_and_a_bad_budget(capsys, tmp_path):
    out = tmp_path / "p.yaml"
    out.write_text("recorded against")
    rc, line = lab(capsys, "plan", "--budget", "smoke", "--out", str(out), "--no-targets")
    assert rc == 2 and "exists" in line and out.read_text() == "recorded against"
    rc, line = lab(capsys, "plan", "--budget", "huge", "--out", str(tmp_path / "q.yaml"))
    assert rc == 2 and "--budget huge: not a budget" in line


def test_session_files_list_the_recorded_groups_and_name_a_label_sheet(smoke_plan, tmp_path):
    doc, _ = smoke_plan
    s01 = [e["group_id"] for e in doc["groups"] if e["session"] == "s01"]
    for gid in s01[:2]:
        (tmp_path / "groups" / gid).mkdir(parents=True)
        (tmp_path / "groups" / gid / "servo.parquet").write_bytes(b"")
        (tmp_path / "groups" / gid / "meta.json").write_text("{}")
    (files,) = [LA.write_session_files(doc, tmp_path)]
    assert files == [tmp_path / "s01.yaml"]
    got = yaml.safe_load(files[0].read_text())
    assert got == dict(session="s01", captures=LA.CAPTURES, takes=[dict(servo=f"groups/{g}") for g in s01[:2]])
    (tmp_path / "s01_labels.csv").write_text("group_id,attached\n")
    LA.write_session_files(doc, tmp_path)
    assert yaml.safe_load(files[0].read_text())["labels"] == "s01_labels.csv"
