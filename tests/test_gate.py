"""The gate's pieces that the corpus (tests/test_gate_corpus.py, slow) exercises only end to end:
limits from config, ids as names, the verdict cache, the sealed-set record, exclusions, and
downstream code that raises instead of dropping a group."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest
import yaml

from embodied_snap import sealed
from embodied_snap.characterize import attachment
from embodied_snap.plan import PlanError, load_plan
from embodied_snap.rawformat import RecordingError, group_dir, group_paths
from embodied_snap.validate import validate_group
from embodied_snap.verdicts import Verdicts

from fakerig import write_fake_raw
from paper_protocol import LIMITS

REPO = Path(__file__).resolve().parent.parent
CFG = yaml.safe_load((REPO / "config.yaml").read_text())


def test_limits_come_from_config_yaml():
    assert LIMITS.max_mocap_gap_s == CFG["resample"]["max_gap_s"]
    assert LIMITS.max_servo_gap_s == CFG["gate"]["max_servo_gap_s"]


@pytest.mark.parametrize("gid", ["../x", "../../etc", "/etc", "a/../../b"])
def test_ids_are_names_not_paths(tmp_path, gid):
    with pytest.raises(RecordingError, match=r"rule: group folder inside the raw directory\)$"):
        group_dir(tmp_path, gid)


def test_symlinked_group_folder_is_refused(tmp_path):
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "raw" / "groups").mkdir(parents=True)
    (tmp_path / "raw" / "groups" / "g1").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(RecordingError, match="outside"):
        group_paths(tmp_path / "raw", "g1")
    assert group_dir(tmp_path / "raw", "g2") == tmp_path / "raw" / "groups" / "g2"


@pytest.fixture
def raw(tmp_path):
    d = tmp_path / "raw_data"
    write_fake_raw(d, ("dyn_0001", "dyn_0002"), duration_s=3.0)
    return d


def test_verdicts_remember_passes_only(raw, tmp_path, monkeypatch):
    import embodied_snap.verdicts as V

    calls = []
    real = V.validate_group
    monkeypatch.setattr(V, "validate_group", lambda *a, **k: (calls.append(a[1]), real(*a, **k))[1])
    cache = tmp_path / "gate.json"
    Verdicts(raw, LIMITS, {}, cache).check(["dyn_0001", "dyn_0002"])
    assert calls == ["dyn_0001", "dyn_0002"]
    Verdicts(raw, LIMITS, {}, cache).check(["dyn_0001", "dyn_0002"])  # a rebuild: nothing re-read
    assert calls == ["dyn_0001", "dyn_0002"]
    # a changed file is judged again; its rejection is not remembered
    p = group_paths(raw, "dyn_0002")["meta"]
    p.write_text(p.read_text().replace('"session"', '"format_version": 2, "session"'))
    for _ in range(2):
        with pytest.raises(RecordingError, match="format version 1"):
            Verdicts(raw, LIMITS, {}, cache).check(["dyn_0001", "dyn_0002"])
    assert calls == ["dyn_0001", "dyn_0002", "dyn_0002", "dyn_0002"]
    # other limits: every verdict is judged again
    Verdicts(raw, replace(LIMITS, max_servo_gap_s=0.04), {}, cache).check(["dyn_0001"])
    assert calls[-1] == "dyn_0001"


def test_stricter_limits_reject_what_defaults_pass(raw):
    validate_group(raw, "dyn_0001", limits=LIMITS)
    with pytest.raises(RecordingError, match=r"rule: tip speed <= 0\.1 m/s"):
        validate_group(raw, "dyn_0001", limits=replace(LIMITS, max_speed_mps={"tip": 0.1}))
    with pytest.raises(RecordingError, match=r"rule: servo log gap <= 0\.005 s"):
        validate_group(raw, "dyn_0001", limits=replace(LIMITS, max_servo_gap_s=0.005))
    with pytest.raises(RecordingError, match=r"rule: labels complete per evidence set"):
        validate_group(raw, "dyn_0001", limits=replace(LIMITS, labels={"dynamics": ["t_attach"]}))


def _plan(ids_cats):
    return pd.DataFrame(
        [
            dict(group_id=g, evidence_set="dynamics", category=c, role="sealed" if c == "sealed" else "train")
            for g, c in ids_cats
        ]
    )


def test_sealed_record_holds_until_resealed(raw):
    plan = _plan([("dyn_0001", "free_space"), ("dyn_0002", "sealed")])
    sealed.check(raw, plan)  # no record yet: nothing to hold
    assert list(sealed.seal(raw, plan, "test")) == ["dyn_0002"]
    sealed.check(raw, plan)
    with pytest.raises(RecordingError, match=r"group dyn_0002: sealed group is now free_space \(train\)"):
        sealed.check(raw, _plan([("dyn_0001", "free_space"), ("dyn_0002", "free_space")]))
    with pytest.raises(
        RecordingError,
        match=r"group dyn_0001: free_space group joined the sealed set|dyn_0001: sealed group joined",
    ):
        sealed.check(raw, _plan([("dyn_0001", "sealed"), ("dyn_0002", "sealed")]))
    with pytest.raises(RecordingError, match="no longer in the plan"):
        sealed.check(raw, _plan([("dyn_0001", "free_space")]))
    p = group_paths(raw, "dyn_0002")["servo"]
    p.write_bytes(p.read_bytes() + b"\0")
    with pytest.raises(
        RecordingError, match=r"servo.parquet: group dyn_0002: recording of a sealed group changed"
    ):
        sealed.check(raw, plan)
    sealed.seal(raw, plan, "esnap seal")  # the explicit re-seal
    sealed.check(raw, plan)


def _cfg(**raw_data):
    cfg = yaml.safe_load((REPO / "config.yaml").read_text())
    cfg["budget"] = "smoke"
    cfg["raw_data"].update(raw_data)
    return cfg


def test_exclusion_keeps_every_other_group_in_place(tmp_path):
    full = load_plan(_cfg(dir=str(tmp_path)))
    ex = load_plan(_cfg(dir=str(tmp_path), exclude={"dyn_0003": "tip marker loose"}))
    assert ex.attrs["excluded"] == {"dyn_0003": "tip marker loose"}
    pd.testing.assert_frame_equal(full[full.group_id != "dyn_0003"].reset_index(drop=True), ex)
    with pytest.raises(PlanError, match="group att_0999: not a group of this run"):
        load_plan(_cfg(dir=str(tmp_path), exclude=["att_0999"]))


def test_twin_index_must_match_the_plan_and_folders_must_be_planned(tmp_path):
    plan = load_plan(_cfg(dir=str(tmp_path)))
    rows = plan.assign(recorded_at="2026-03-01T10:00:00", n_mocap=1, n_servo=1)
    cols = ["group_id", "evidence_set", "category", "session", "recorded_at", "n_mocap", "n_servo"]
    rows.loc[rows.group_id == "dyn_0007", "category"] = "free_space"
    rows[cols].to_csv(tmp_path / "index.csv", index=False)
    with pytest.raises(PlanError, match=r"group dyn_0007: category 'free_space' but the plan says 'sealed'"):
        load_plan(_cfg(dir=str(tmp_path)))
    os.remove(tmp_path / "index.csv")
    (tmp_path / "groups" / "stray_0001").mkdir(parents=True)
    with pytest.raises(
        PlanError, match=r"groups/stray_0001: group stray_0001: .*every group has an index row"
    ):
        load_plan(_cfg(dir=str(tmp_path)))


def test_attachment_fit_raises_on_an_unmeasurable_trial():
    rows = [
        dict(group_id=f"att_{i:04d}", session="s01", v_peak=1.0, tilt_deg=5.0, attached=i % 2)
        for i in range(4)
    ]
    rows[2]["tilt_deg"] = float("nan")
    with pytest.raises(RecordingError, match="group att_0002: .*rule: attachment trial measurable"):
        attachment.fit(rows, 1.0)


def _edits():
    nan = float("nan")
    return {
        "none": (lambda m: m, lambda s: s),
        "nan in a valid pose": (lambda m: m.assign(tip_x=m.tip_x.where(m.index != 5, nan)), None),
        "inf position": (lambda m: m.assign(s1_y=m.s1_y.where(m.index != 5, float("inf"))), None),
        "6 m away": (lambda m: m.assign(base_z=m.base_z + 6), None),
        "long quaternion": (lambda m: m.assign(tip_qw=m.tip_qw * 1.01), None),
        "repeated t": (lambda m: m.assign(t=m.t.where(m.index != 9, m.t.shift(1))), None),
        "t NaN": (
            lambda m: m.assign(t=m.t.where(m.index != 0, nan)),
            lambda s: s.assign(t=s.t.where(s.index != 0, nan)),
        ),
        "t as int": (lambda m: m.assign(t=(m.t * 1000).astype("int64")), None),
        "t as float32": (lambda m: m.assign(t=m.t.astype("float32")), lambda s: s.assign(t=s.t.astype("float32"))),
        "columns reordered": (lambda m: m[list(reversed(m.columns))], lambda s: s[list(reversed(s.columns))]),
        "valid as int": (lambda m: m.assign(s2_valid=m.s2_valid.astype(int)), None),
        "nullable int ticks": (None, lambda s: s.assign(goal_1=s.goal_1.astype("Int64").where(s.index != 3, pd.NA))),
        "float ticks": (None, lambda s: s.assign(present_2=s.present_2 + 0.5)),
        "ticks out of range": (None, lambda s: s.assign(goal_4=s.goal_4.where(s.index != 3, 2_000_000))),
        "current NaN": (None, lambda s: s.assign(current_5=s.current_5.where(s.index != 3, nan))),
        "current as bool": (None, lambda s: s.assign(current_6=s.current_6 > 0)),
        "current in A x1000": (None, lambda s: s.assign(current_7=s.current_7 * 1e3)),
        # The mocap time base (rule "mocap rate constant, 100-500 Hz"); the frame is 240 Hz.
        "mocap at 120 Hz": (lambda m: m.iloc[::2].reset_index(drop=True), None),
        "mocap at 30 Hz": (lambda m: m.iloc[::8].reset_index(drop=True), None),
        "mocap clock at 600 Hz": (lambda m: m.assign(t=m.t.iloc[0] + (m.t - m.t.iloc[0]) * 0.4), None),
        "mocap clock at 100 Hz": (lambda m: m.assign(t=m.t.iloc[0] + (m.t - m.t.iloc[0]) * 2.4), None),
        "every 10th mocap row missing": (lambda m: m.drop(index=m.index[9::10]).reset_index(drop=True), None),
        "mocap intervals off by 0.5 %": (lambda m: m.assign(t=m.t + (m.index % 2) * 0.005 / 240), None),
        "mocap intervals off by 2 %": (lambda m: m.assign(t=m.t + (m.index % 2) * 0.02 / 240), None),
        "mocap rate 240 then 360 Hz": (
            lambda m: m.assign(t=m.t.where(m.index < 300, m.t.iloc[300] + (m.index - 300) / 360.0)), None),
        "mocap t inf": (lambda m: m.assign(t=m.t.where(m.index != len(m) - 1, float("inf"))), None),
    }


# Edits the schema passes: the fast path must pass them too (it only doubts what it cannot check).
_BOTH_PASS = ("none", "mocap at 120 Hz", "mocap clock at 100 Hz",
              "every 10th mocap row missing", "mocap intervals off by 0.5 %")
# Time bases the schema refuses (and so the fast path, by the assertion above).
_SCHEMA_REFUSES = ("mocap at 30 Hz", "mocap clock at 600 Hz", "mocap intervals off by 2 %",
                   "mocap rate 240 then 360 Hz", "mocap t inf")


@pytest.mark.parametrize("edit", list(_edits()))
def test_fast_path_passes_only_what_pandera_passes(raw, edit):
    """The vectorised pre-check may doubt a good frame (pandera then decides), never pass a bad one."""
    import pandera.errors as pe

    from embodied_snap import rawschema as R

    fm, fs = _edits()[edit]
    p = group_paths(raw, "dyn_0001")
    for fn, frame, fast, schema in (
        (fm, pd.read_parquet(p["mocap"]), R._mocap_passes, R.mocap_schema()),
        (fs, pd.read_parquet(p["servo"]), R._servo_passes, R.servo_schema()),
    ):
        if fn is None:
            continue
        df = fn(frame.copy())
        try:
            schema.validate(df)
            ok = True
        except (pe.SchemaError, pe.SchemaErrors):
            ok = False
        assert not fast(df) or ok
        if edit in _BOTH_PASS:
            assert fast(df) and ok
        if edit in _SCHEMA_REFUSES:
            assert not ok


@pytest.mark.parametrize(
    "edit",
    [
        {},
        {"session": ""},
        {"group_id": 7},
        {"category": None},
        {"evidence_set": "dynamic"},
        {"category": "sealed", "evidence_set": "attachment"},
        {"session": "séance"},
    ],
    ids=repr,
)
def test_meta_fast_path_passes_only_what_pandera_passes(raw, edit):
    """meta.json's plain-Python pre-check may doubt good keys (pandera decides), never pass bad ones."""
    import json

    import pandera.errors as pe

    from embodied_snap import rawschema as R

    meta = {**json.loads(group_paths(raw, "dyn_0001")["meta"].read_text()), **edit}
    frame = pd.DataFrame([{k: meta[k] for k in R.META_KEYS if k in meta}])
    try:
        R.meta_schema().validate(frame)
        ok = True
    except (pe.SchemaError, pe.SchemaErrors):
        ok = False
    assert not R._meta_passes(meta) or ok
    if not edit:
        assert R._meta_passes(meta) and ok


_INDEX_EDITS = {
    "none": lambda d: d,
    "id repeated": lambda d: d.assign(group_id=d.group_id.iloc[0]),
    "id with a slash": lambda d: d.assign(group_id=["a/b", "c"]),
    "id not ascii": lambda d: d.assign(group_id=["dyn_é", "dyn_0002"]),
    "unknown set": lambda d: d.assign(evidence_set="dynamic"),
    "category of another set": lambda d: d.assign(category="sealed"),
    "empty session": lambda d: d.assign(session=""),
    "empty id": lambda d: d.assign(group_id=["", "dyn_0002"]),
    "date not iso": lambda d: d.assign(recorded_at="5 Dec 2026"),
    "date with zone": lambda d: d.assign(recorded_at="2026-12-05T10:00:00+01:00"),
    "count negative": lambda d: d.assign(n_mocap="-1"),
    "count a float": lambda d: d.assign(n_servo="12.0"),
    "count padded": lambda d: d.assign(n_servo=" 12"),
    "count leading zero": lambda d: d.assign(n_mocap="0720"),
    "count empty": lambda d: d.assign(n_mocap=""),
    "columns reordered": lambda d: d[[d.columns[1], d.columns[0], *d.columns[2:]]],
    "extra column": lambda d: d.assign(note="x"),
    "column missing": lambda d: d.drop(columns="session"),
}
# Edits the schema passes: the pre-check must pass them too (and give pandera's frame).
_INDEX_BOTH_PASS = ("none", "date with zone", "count leading zero")


@pytest.mark.parametrize("edit", list(_INDEX_EDITS))
def test_index_fast_path_passes_only_what_pandera_passes(raw, edit):
    """index.csv's pre-check may doubt a good table (pandera then decides), never pass a bad one;
    what it passes is the schema's own output (the row counts coerced to int64)."""
    import pandera.errors as pe

    from embodied_snap import rawschema as R
    from embodied_snap.validate import GROUP_ID_PATTERN

    df = _INDEX_EDITS[edit](pd.read_csv(raw / "index.csv", dtype=str, keep_default_na=False))
    try:
        want = R.index_schema(GROUP_ID_PATTERN).validate(df.copy())
    except (pe.SchemaError, pe.SchemaErrors):
        want = None
    fast = R._index_passes(df, GROUP_ID_PATTERN)
    assert not fast or want is not None
    if edit in _INDEX_BOTH_PASS:
        assert fast and want is not None
        pd.testing.assert_frame_equal(R.check_index(df, "index.csv", GROUP_ID_PATTERN, str), want)


def test_a_good_tree_is_gated_without_pandera(raw):
    """pandera is imported only to name a broken rule: a good index and good groups pass the
    pre-checks alone (its import and first schema were 0.26 s of every workflow parse)."""
    import subprocess
    import sys

    code = (
        "import sys; from embodied_snap.validate import read_index, validate_group; "
        "from paper_protocol import LIMITS; "
        f"rows = read_index({str(raw)!r}).to_dict('records'); "
        f"[validate_group({str(raw)!r}, r['group_id'], r, limits=LIMITS) for r in rows]; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'pandera'))"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parent)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "[]", out.stdout[:300]


def test_recording_read_once_is_the_file(raw):
    """The gate parses and hashes the same bytes: the frame and the manifest entry are the file's."""
    from embodied_snap import rawschema as R

    p = group_paths(raw, "dyn_0001")["mocap"]
    frame, data = R.load_recording(p, "dyn_0001")
    pd.testing.assert_frame_equal(frame, pd.read_parquet(p), check_exact=True)
    assert R.file_entry(p, data) == R.file_entry(p)


# --- the raw directory is closed ------------------------------------------------------------


def _link_out(raw, tmp_path, gid, name, target=None):
    """Replace a group's file by a symlink out of the raw directory (to a copy, or to `target`)."""
    p = raw / "groups" / gid / name
    if target is None:
        target = tmp_path / "elsewhere" / name
        target.parent.mkdir(exist_ok=True)
        target.write_bytes(p.read_bytes())
    p.unlink()
    p.symlink_to(target)
    return target


@pytest.mark.parametrize("name", ["mocap.parquet", "servo.parquet", "meta.json"])
def test_a_file_linked_out_is_refused_before_it_is_opened(raw, tmp_path, name):
    from gate_corpus import opened_any, opens

    target = _link_out(raw, tmp_path, "dyn_0002", name)
    rule = r"\(rule: file inside the raw directory\)$"
    with opens() as seen:
        with pytest.raises(RecordingError, match=rf"groups/dyn_0002/{name}: group dyn_0002: a link to .*{rule}"):
            Verdicts(raw, LIMITS, {}, None).check(["dyn_0001", "dyn_0002"])
        with pytest.raises(RecordingError, match=rule):
            group_paths(raw, "dyn_0002")  # so no job is handed the path either
    assert seen and not opened_any(seen, [str(target.resolve())])


def test_a_link_to_etc_passwd_is_never_read(raw, tmp_path):
    from gate_corpus import opened_any, opens

    _link_out(raw, tmp_path, "dyn_0001", "meta.json", target=Path("/etc/passwd"))
    with opens() as seen, pytest.raises(RecordingError, match="a link to /etc/passwd, outside"):
        validate_group(raw, "dyn_0001", limits=LIMITS)
    assert not opened_any(seen, [os.path.realpath("/etc/passwd")])


def test_groups_folder_linked_out_is_refused(raw, tmp_path):
    import shutil

    shutil.move(raw / "groups", tmp_path / "moved")
    (raw / "groups").symlink_to(tmp_path / "moved")
    with pytest.raises(RecordingError, match=r"group dyn_0001: resolves to .*moved/dyn_0001, outside .*"
                       r"\(rule: group folder inside the raw directory\)$"):
        group_paths(raw, "dyn_0001")


def test_index_and_sealed_record_linked_out_are_refused(raw, tmp_path):
    from gate_corpus import opened_any, opens

    from embodied_snap.validate import read_index

    for name in ("index.csv", "sealed.json"):
        target = tmp_path / "elsewhere" / name
        target.parent.mkdir(exist_ok=True)
        target.write_text("group_id\n" if name == "index.csv" else '{"groups": {}}')
        (raw / name).unlink(missing_ok=True)
        (raw / name).symlink_to(target)
        with opens() as seen, pytest.raises(RecordingError, match=rf"{name}: group -: a link to .*outside"):
            read_index(raw) if name == "index.csv" else sealed.check(raw, _plan([("dyn_0001", "sealed")]))
        assert not opened_any(seen, [str(target.resolve())])


def test_a_link_that_stays_inside_is_allowed(raw):
    p = raw / "groups" / "dyn_0001" / "servo.parquet"
    (raw / ".store").mkdir()
    p.rename(raw / ".store" / "servo.parquet")
    p.symlink_to(Path("..", "..", ".store", "servo.parquet"))
    validate_group(raw, "dyn_0001", limits=LIMITS)
    (raw / "groups" / "dyn_0002").rename(raw / ".store" / "dyn_0002")
    (raw / "groups" / "dyn_0002").symlink_to(raw / ".store" / "dyn_0002")
    validate_group(raw, "dyn_0002", limits=LIMITS)


# --- one gate in every mode -----------------------------------------------------------------


def _twin_tree(tmp_path):
    """Two recorded groups of a tiny simulated-rig budget (fakerig's, as the twin would name them)."""
    from fakerig import write_fake_group

    cfg = _cfg(dir=str(tmp_path / "raw_data"), source="twin")
    cfg["budgets"]["tiny"] = {**cfg["budgets"]["smoke"], "groups": {"dynamics": {"free_space": 3}}}
    cfg["budgets"]["tiny"]["split"] = {"validation": 1}
    cfg["budget"] = "tiny"
    rows = [
        write_fake_group(tmp_path / "raw_data", g, seed=i, duration_s=3.0, session=f"s{i + 1:02d}")
        for i, g in enumerate(("dyn_0001", "dyn_0002", "dyn_0003"))
    ]
    return cfg, tmp_path / "raw_data", rows


def test_twin_row_counts_are_checked_once_index_csv_exists(tmp_path):
    """The simulated rig's first run writes index.csv after recording; from then on, in that run's
    successors, its row counts are the gate's like any rig's, the remembered passes included."""
    from embodied_snap.rawformat import write_index
    from embodied_snap.verdicts import check_tree, gate_tree

    cfg, raw, rows = _twin_tree(tmp_path)
    cache = tmp_path / "gate.json"
    plan, _ = gate_tree(cfg, raw, cache)  # before index.csv: the plan's rows, passes remembered
    assert sorted(plan.group_id) == ["dyn_0001", "dyn_0002", "dyn_0003"]
    rows[1]["n_mocap"] += 1
    write_index(rows, raw / "index.csv")
    want = r"index.csv: group dyn_0002: n_mocap \d+ but mocap.parquet has \d+ rows \(rule: n_mocap matches"
    with pytest.raises(RecordingError, match=want):
        gate_tree(cfg, raw, cache)
    with pytest.raises(RecordingError, match=want):
        check_tree(cfg, raw)  # esnap validate: the same line
    # a shard not recorded yet is judged when it is (the workflow's acquisition checkpoint)
    gate_tree(cfg, raw, cache, recorded=lambda shard: False)
