"""Validation of raw recordings: valid fakerig groups pass; a corpus of broken ones is caught.

Each broken kind starts from a copy of a valid raw_data/ and breaks one thing; the check must
raise a one-line RecordingError naming the file, the group and the rule that the kind breaks.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from embodied_snap.io import write_json, write_parquet
from embodied_snap.rawformat import group_dir, group_paths
from embodied_snap.resample import resample_group
from embodied_snap.validate import RecordingError, validate_group, validate_index, validate_shard

from fakerig import write_fake_group, write_fake_raw
from paper_protocol import LIMITS

G = "dyn_0001"
GROUPS = (G, "dyn_0002")
DURATION_S = 3.0


@pytest.fixture(scope="session")
def template(tmp_path_factory):
    raw = tmp_path_factory.mktemp("template") / "raw_data"
    write_fake_raw(raw, GROUPS, duration_s=DURATION_S)
    return raw


@pytest.fixture
def raw(template, tmp_path):
    dst = tmp_path / "raw_data"
    shutil.copytree(template, dst)
    return dst


def validate_all(raw):
    index = validate_index(raw, LIMITS)
    return validate_shard(raw, list(index.group_id), index, LIMITS)


# --- valid groups ----------------------------------------------------------------------------


def test_valid_groups_pass(raw):
    manifest = validate_all(raw)
    assert [m["group_id"] for m in manifest] == list(GROUPS)
    m = manifest[0]
    assert (m["evidence_set"], m["category"], m["session"]) == ("dynamics", "free_space", "s01")
    assert m["n_mocap"] == int(DURATION_S * 240) + 1
    assert m["duration_s"] == pytest.approx(DURATION_S)
    assert 0.9 < m["mocap_valid_fraction"] < 1.0  # fakerig drops a few samples
    for name in ("mocap.parquet", "servo.parquet", "meta.json"):
        f = m["files"][name]
        data = Path(f["path"]).read_bytes()
        assert f["sha256"] == hashlib.sha256(data).hexdigest() and f["bytes"] == len(data)


def test_validate_group_without_index_row(raw):
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G


def test_fakerig_and_manifest_are_deterministic(raw, tmp_path):
    other = tmp_path / "again"
    write_fake_raw(other, GROUPS, duration_s=DURATION_S)
    a, b = validate_all(raw), validate_all(other)
    assert [{k: v["sha256"] for k, v in m["files"].items()} for m in a] == [
        {k: v["sha256"] for k, v in m["files"].items()} for m in b
    ]


def test_shard_group_missing_from_index(raw):
    index = validate_index(raw, LIMITS)
    with pytest.raises(RecordingError, match=r"group dyn_0042: .*\(rule: every group has an index row\)$"):
        validate_shard(raw, ["dyn_0042"], index, LIMITS)


def test_error_pickles():
    import pickle

    e = pickle.loads(pickle.dumps(RecordingError("a/b", "g", "bad", "r")))
    assert str(e) == "a/b: group g: bad (rule: r)"


# --- helpers that break one thing --------------------------------------------------------------


def _sync_index(raw):
    """Keep index.csv row counts in step with the files, so only the intended rule breaks."""
    idx = pd.read_csv(raw / "index.csv", dtype=str, keep_default_na=False)
    for i, gid in enumerate(idx.group_id):
        p = group_paths(raw, gid)
        if p["mocap"].exists() and p["servo"].exists():
            idx.loc[i, "n_mocap"] = str(pq.read_metadata(p["mocap"]).num_rows)
            idx.loc[i, "n_servo"] = str(pq.read_metadata(p["servo"]).num_rows)
    idx.to_csv(raw / "index.csv", index=False)


def _edit(kind):
    """Decorator factory: rewrite one group's mocap/servo frame with `fn`, then sync the index."""

    def wrap(fn):
        def apply(raw):
            p = group_paths(raw, G)[kind]
            write_parquet(fn(pd.read_parquet(p)), p)
            _sync_index(raw)

        return apply

    return wrap


def _edit_index(fn):
    def apply(raw):
        idx = pd.read_csv(raw / "index.csv", dtype=str, keep_default_na=False)
        fn(idx).to_csv(raw / "index.csv", index=False)

    return apply


def _edit_meta(fn):
    def apply(raw):
        p = group_paths(raw, G)["meta"]
        meta = json.loads(p.read_text())
        fn(meta)
        write_json(meta, p)

    return apply


def _set(df, cols, rows, value):
    df.loc[rows, cols] = value
    return df


@_edit("mocap")
def nan_in_valid_sample(df):
    return _set(df, "tip_x", df.index[100:110], np.nan)  # tip_valid stays True


@_edit("mocap")
def time_backwards(df):
    t = df["t"].to_numpy().copy()
    t[[200, 201]] = t[[201, 200]]
    df["t"] = t
    return df


@_edit("mocap")
def duplicate_timestamps(df):
    df.loc[300, "t"] = df.loc[299, "t"]
    return df


@_edit("mocap")
def mocap_rate_30hz(df):  # 120 Hz is a rate the format accepts (100-500 Hz); 30 Hz is not
    return df.iloc[::8].reset_index(drop=True)


@_edit("mocap")
def positions_in_mm(df):
    pos = [c for c in df if c[-2:] in ("_x", "_y", "_z")]
    df[pos] = df[pos] * 1000.0
    return df


@_edit("mocap")
def non_unit_quaternion(df):
    q = ["tip_qw", "tip_qx", "tip_qy", "tip_qz"]
    df[q] = df[q] * 1.05
    return df


@_edit("mocap")
def t_integer_milliseconds(df):
    df["t"] = np.round(df["t"] * 1000).astype(np.int64)
    return df


@_edit("mocap")
def valid_flag_not_bool(df):
    df["tip_valid"] = df["tip_valid"].astype(np.int64)
    return df


@_edit("mocap")
def mocap_missing_column(df):
    return df.drop(columns="tip_qw")


@_edit("mocap")
def mocap_extra_column(df):
    df["tip_speed"] = 0.0
    return df


@_edit("servo")
def servo_renamed_column(df):
    return df.rename(columns={"present_4": "position_4"})


@_edit("servo")
def servo_ticks_float(df):
    df["goal_2"] = df["goal_2"].astype(float) + 0.5
    return df


@_edit("servo")
def servo_ticks_out_of_range(df):
    df.loc[10, "present_5"] = 5_000_000
    return df


@_edit("servo")
def servo_current_missing(df):
    return df.drop(columns="current_7")


@_edit("servo")
def servo_log_too_short(df):
    return df.iloc[: len(df) // 2]


@_edit("servo")
def servo_rate_10hz(df):
    return df.iloc[::10].reset_index(drop=True)


def truncated_parquet(raw):
    p = group_paths(raw, G)["mocap"]
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])


def long_mocap_dropout(raw):
    @_edit("mocap")
    def drop(df):
        rows = df.index[240:312]  # 0.3 s of tip samples lost, 0.1 s allowed
        df.loc[rows, "tip_valid"] = False
        return _set(df, ["tip_x", "tip_y", "tip_z"], rows, np.nan)

    drop(raw)


def index_row_without_files(raw):
    idx = pd.read_csv(raw / "index.csv", dtype=str, keep_default_na=False)
    row = idx.iloc[[0]].assign(group_id="dyn_0099")
    pd.concat([idx, row]).to_csv(raw / "index.csv", index=False)


def files_without_index_row(raw):
    write_fake_group(raw, "dyn_0003", duration_s=1.0)


def meta_not_json(raw):
    group_paths(raw, G)["meta"].write_text('{"group_id": "dyn_0001", ')


def _index_value(col, value):
    """Set one field of G's index.csv row."""
    return _edit_index(lambda i: i.assign(**{col: np.where(i.group_id == G, value, i[col])}))


# kind -> (break it, the file the message must name [as kind:group when not G's], the rule)
CORPUS = {
    "truncated parquet": (truncated_parquet, "mocap", "readable parquet"),
    "missing column": (mocap_missing_column, "mocap", "required columns"),
    "extra column": (mocap_extra_column, "mocap", "no extra columns"),
    "renamed column": (servo_renamed_column, "servo", "no extra columns"),
    "NaN span in a valid sample": (nan_in_valid_sample, "mocap", "valid tip samples complete"),
    "time going backwards": (time_backwards, "mocap", "t strictly increasing"),
    "duplicate timestamps": (duplicate_timestamps, "mocap", "t strictly increasing"),
    "mocap at 30 Hz": (mocap_rate_30hz, "mocap", "mocap rate constant, 100-500 Hz"),
    "positions in mm": (positions_in_mm, "mocap", "bodies within 2 m of the base"),
    "non-unit quaternion": (non_unit_quaternion, "mocap", "unit tip quaternions"),
    "t as integer milliseconds": (t_integer_milliseconds, "mocap", "column dtype"),
    "valid flag not bool": (valid_flag_not_bool, "mocap", "column dtype"),
    "servo ticks as floats": (servo_ticks_float, "servo", "ticks are integers"),
    "servo ticks out of range": (servo_ticks_out_of_range, "servo", "ticks in range"),
    "servo current column missing": (servo_current_missing, "servo", "required columns"),
    "servo log too short": (servo_log_too_short, "servo", "servo log covers mocap"),
    "servo at 10 Hz": (servo_rate_10hz, "servo", "servo rate about 100 Hz"),
    "duplicate group id": (_edit_index(lambda i: pd.concat([i, i.iloc[[0]]])), "index", "unique group_id"),
    "unknown evidence set": (_index_value("evidence_set", "dynamix"), "index", "known evidence set"),
    "unknown category": (_index_value("category", "freespace"), "index", "known category"),
    "recorded_at not a time": (_index_value("recorded_at", "yesterday"), "index", "recorded_at is ISO 8601"),
    "n_servo not a number": (_index_value("n_servo", "many"), "index", "column dtype"),
    "n_mocap mismatch": (_index_value("n_mocap", "999"), "index", "n_mocap matches mocap.parquet"),
    "index row without files": (index_row_without_files, "mocap:dyn_0099", "index row has its files"),
    "files without index row": (files_without_index_row, "dir:dyn_0003", "every group has an index row"),
    "meta.json not JSON": (meta_not_json, "meta", "meta.json is JSON"),
    "meta.json missing key": (_edit_meta(lambda m: m.pop("session")), "meta", "required keys"),
    "meta.json group_id mismatch": (
        _edit_meta(lambda m: m.update(group_id="dyn_0002")),
        "meta",
        "meta group_id matches folder",
    ),
    "meta.json disagrees with index": (
        _edit_meta(lambda m: m.update(category="target")),
        "meta",
        "meta.json agrees with index.csv",
    ),
    # The gate's dropout rule: what resampling bridges (resample.max_gap_s) is what passes.
    "long mocap dropout": (long_mocap_dropout, "mocap", "mocap dropout <= 0.1 s"),
}


def _expected(raw, where):
    """The file (and group) a kind's message must name."""
    kind, _, gid = where.partition(":")
    gid = gid or G
    if kind == "index":
        return raw / "index.csv", gid
    if kind == "dir":
        return group_dir(raw, gid), gid
    return group_paths(raw, gid)[kind], gid


@pytest.mark.parametrize("kind", list(CORPUS))
def test_broken_recording_is_rejected(raw, kind):
    breaks, where, rule = CORPUS[kind]
    breaks(raw)
    with pytest.raises(RecordingError) as exc:
        validate_all(raw)
    msg = str(exc.value)
    path, gid = _expected(raw, where)
    assert "\n" not in msg
    assert msg.startswith(f"{path}: group {gid}: "), msg
    assert msg.endswith(f"(rule: {rule})"), msg


def test_corpus_has_at_least_15_kinds():
    assert len(CORPUS) >= 15


def test_long_dropout_message_names_body_and_span(raw):
    long_mocap_dropout(raw)
    with pytest.raises(
        RecordingError, match=r"tip not tracked for 0\.30\d s from t=13\.49\d to t=13\.80\d s"
    ):
        validate_all(raw)
    # Resampling does not decide again; met anyway, the group stops the job, never vanishes.
    with pytest.raises(RecordingError, match=r"rule: recording passed the gate"):
        resample_group(raw, G, 50.0, 0.1)
