"""One recording, one group: the gate refuses two groups that hold the same file (a symlink inside
the raw directory, a hard link) or the same bytes (a copied take), in one line naming both, from
the stats and hashes it takes anyway; `esnap import` refuses a take already imported. The corpus
(tests/gate_corpus.py) has these kinds end to end."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pandas as pd
import pytest
import yaml
from test_capture_import import digest, export, run_import

from embodied_snap.rawformat import RecordingError
from embodied_snap.validate import check_one_recording, validate_index, validate_shard
from embodied_snap.verdicts import Verdicts

from fakerig import write_fake_raw
from paper_protocol import LIMITS

IDS = ["dyn_0001", "dyn_0002", "dyn_0003"]
RULE = r"\(rule: one recording, one group\)$"


@pytest.fixture
def raw(tmp_path):
    d = tmp_path / "raw_data"
    write_fake_raw(d, IDS, duration_s=3.0)
    return d


def judged(monkeypatch) -> list[str]:
    """The groups the gate reads (validate_group) from now on."""
    import embodied_snap.verdicts as V

    calls, real = [], V.validate_group
    monkeypatch.setattr(V, "validate_group", lambda *a, **k: (calls.append(a[1]), real(*a, **k))[1])
    return calls


def copy_into(raw, name, src="dyn_0001", dst="dyn_0003"):
    p = raw / "groups" / dst / name
    p.unlink()
    shutil.copyfile(raw / "groups" / src / name, p)


@pytest.mark.parametrize("name", ["mocap.parquet", "servo.parquet"])
@pytest.mark.parametrize("link", ["symlink", "hard link"])
def test_another_groups_file_is_refused_before_it_is_read(raw, monkeypatch, name, link):
    p = raw / "groups" / "dyn_0003" / name
    p.unlink()
    if link == "symlink":
        p.symlink_to(Path("..", "dyn_0001", name))  # stays inside: allowed as a link
    else:
        os.link(raw / "groups" / "dyn_0001" / name, p)
    calls = judged(monkeypatch)
    want = rf"groups/dyn_0003/{name}: group dyn_0003: the same file as \S+/dyn_0001/{name} of group dyn_0001 {RULE}"
    with pytest.raises(RecordingError, match=want):
        Verdicts(raw, LIMITS, {}, None).check(IDS)
    assert calls == ["dyn_0001", "dyn_0002"]  # refused from its stat alone


@pytest.mark.parametrize("name", ["mocap.parquet", "servo.parquet"])
def test_a_copied_recording_is_refused_from_the_remembered_hashes(raw, tmp_path, monkeypatch, name):
    cache = tmp_path / "gate.json"
    Verdicts(raw, LIMITS, {}, cache).check(IDS)
    copy_into(raw, name)
    calls = judged(monkeypatch)
    want = rf"groups/dyn_0003/{name}: group dyn_0003: the same bytes as \S+/dyn_0001/{name} of group dyn_0001 {RULE}"
    for _ in range(2):  # the copy passes alone and is remembered; the rule is judged again each time
        with pytest.raises(RecordingError, match=want):
            Verdicts(raw, LIMITS, {}, cache).check(IDS)
    assert calls == ["dyn_0003"]  # the changed group read once, the others never: hashes from the cache


def test_the_validate_index_job_applies_the_rule_across_shard_records(raw):
    """What the job reads: each shard's manifest entries (sha256 per file), written by shards judged apart."""
    copy_into(raw, "servo.parquet", src="dyn_0002")
    index = validate_index(raw, LIMITS)
    shards = [validate_shard(raw, ids, index, LIMITS) for ids in (IDS[:2], IDS[2:])]
    with pytest.raises(RecordingError, match=rf"dyn_0003/servo.parquet: group dyn_0003: the same bytes as "
                                             rf"\S+dyn_0002/servo.parquet of group dyn_0002 {RULE}"):
        check_one_recording(e for s in shards for e in s)


# --- esnap import ----------------------------------------------------------------------------------


def imported(tmp_path, capsys, monkeypatch):
    """A session imported into tmp/raw: (session, lab, raw, takes folder, digest of raw)."""
    session, lab, _, _ = export(tmp_path)
    raw = tmp_path / "raw"
    assert run_import(capsys, monkeypatch, session, lab, raw)[0] == 0
    return session, lab, raw, tmp_path / "lab" / "takes", digest(raw)


def test_a_session_imported_again_is_refused_by_its_takes(tmp_path, capsys, monkeypatch):
    session, lab, raw, takes, before = imported(tmp_path, capsys, monkeypatch)
    rc, _, err = run_import(capsys, monkeypatch, session, lab, raw)
    assert rc == 1 and err == [f"error: {takes / 'dyn_0001.csv'}: take dyn_0001: already imported as group "
                               f"dyn_0001 in {raw} (rule: one recording, one group) (nothing written to {raw})"], err
    assert digest(raw) == before


def test_a_take_imported_again_under_a_new_id_is_refused(tmp_path, capsys, monkeypatch):
    session, lab, raw, takes, before = imported(tmp_path, capsys, monkeypatch)
    doc = yaml.safe_load(session.read_text())
    sheet = pd.read_csv(session.with_name(doc["labels"]), dtype=str, keep_default_na=False)
    sheet[sheet.group_id == "dyn_0002"].assign(group_id="dyn_0003").to_csv(session.with_name("again.csv"), index=False)
    again = session.with_name("again.yaml")
    take = {**doc["takes"][1], "group_id": "dyn_0003"}
    again.write_text(yaml.safe_dump({**doc, "labels": "again.csv", "takes": [take]}))
    rc, _, err = run_import(capsys, monkeypatch, again, lab, raw)
    assert rc == 1 and err == [f"error: {takes / 'dyn_0002.csv'}: take dyn_0003: already imported as group "
                               f"dyn_0002 in {raw} (rule: one recording, one group) (nothing written to {raw})"], err
    assert digest(raw) == before


def test_a_take_copied_within_a_session_is_refused(tmp_path, capsys, monkeypatch):
    session, lab, _, _ = export(tmp_path)
    takes = tmp_path / "lab" / "takes"
    shutil.copyfile(takes / "dyn_0001.csv", takes / "dyn_0002.csv")
    raw = tmp_path / "raw"
    rc, _, err = run_import(capsys, monkeypatch, session, lab, raw)
    assert rc == 1 and err == [f"error: {takes / 'dyn_0002.csv'}: take dyn_0002: the same export as take dyn_0001 "
                               f"of this session (rule: one recording, one group) (nothing written to {raw})"], err
    assert not raw.exists()
