"""The gate at its edges (issue 27, item 4): a value just inside a limit passes, just outside is
refused. Expected values come from config.yaml and the recording's own clock, never from the gate.

fakerig writes a 240 Hz recording from t0 = 12.5 s; a 3 s group ends at exactly 15.5 s (both are
binary-exact, so "just outside" by a millisecond is unambiguous)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pandera.pandas as pa
import pytest
import yaml

from embodied_snap import rawschema as RS
from embodied_snap.io import write_json, write_parquet
from embodied_snap.rawformat import group_paths
from embodied_snap.validate import RecordingError, validate_group

from fakerig import write_fake_group
from paper_protocol import LIMITS

G = "dyn_0001"
T0, DURATION_S, HZ = 12.5, 3.0, 240.0
T_END = T0 + DURATION_S
CONFIG = yaml.safe_load((Path(__file__).resolve().parent.parent / "config.yaml").read_text())
# config.yaml gate.max_speed_mps, written out: the gate's defaults must be these numbers.
MAX_SPEED = {"base": 3.0, "s1": 6.0, "s2": 8.0, "tip": 10.0, "target": 5.0}


def test_config_speed_limits_are_the_ones_tested_here():
    assert CONFIG["gate"]["max_speed_mps"] == MAX_SPEED


def _group(tmp_path, category="free_space", **kw):
    """One valid dynamics group; category "target" (config gate.target_groups) tracks the target."""
    raw = tmp_path / "raw_data"
    write_fake_group(raw, G, category=category, duration_s=DURATION_S, t0=T0, **kw)
    if category == "target":
        p = group_paths(raw, G)["meta"]
        write_json({**json.loads(p.read_text()), "target": {"position": [0.45, 1.05, 0.10]}}, p)
    return raw


def _set_label(raw, key, value):
    p = group_paths(raw, G)["meta"]
    meta = json.loads(p.read_text())
    meta["labels"][key] = value
    write_json(meta, p)


# --- label times: inside [first sample, last sample], both ends included --------------------------


@pytest.mark.parametrize("key", ["t_s1", "t_s2", "t_preload"])
def test_label_just_after_the_recording_end_is_refused(tmp_path, key):
    raw = _group(tmp_path)
    _set_label(raw, key, T_END + 0.001)
    with pytest.raises(RecordingError, match=rf"label {key}=15\.501 is not a time in 12\.500\.\.15\.500 s"):
        validate_group(raw, G, limits=LIMITS)


def test_label_just_before_the_recording_start_is_refused(tmp_path):
    raw = _group(tmp_path)
    _set_label(raw, "t_preload", T0 - 0.001)
    with pytest.raises(RecordingError, match=r"rule: label times inside the recording"):
        validate_group(raw, G, limits=LIMITS)


def test_labels_on_the_first_and_last_sample_pass(tmp_path):
    raw = _group(tmp_path)
    _set_label(raw, "t_preload", T0)
    _set_label(raw, "t_s1", T_END)
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G


@pytest.mark.parametrize("value", [True, "15.0", [14.0]])
def test_a_label_time_that_is_not_a_number_is_refused(tmp_path, value):
    raw = _group(tmp_path)
    _set_label(raw, "t_s1", value)
    with pytest.raises(RecordingError, match=r"rule: label times inside the recording"):
        validate_group(raw, G, limits=LIMITS)


# --- speed limits: one jump of a known size between two consecutive 240 Hz samples -----------------


def _jump(raw, body, factor, at_s=1.0):
    """Shift `body` by factor * limit * (1/240 s) along x from the sample at t0 + at_s on: its speed
    is zero everywhere (a static arm) except factor * limit across that one interval."""
    p = group_paths(raw, G)["mocap"]
    df = pd.read_parquet(p)
    k = int(round(at_s * HZ))
    assert df[f"{body}_valid"].iloc[k - 1 : k + 1].all()
    step = factor * MAX_SPEED[body] / HZ
    df.loc[df.index[k:], f"{body}_x"] += step
    write_parquet(df, p)
    return step


@pytest.mark.parametrize("body", sorted(MAX_SPEED))
def test_a_speed_just_over_each_body_limit_is_refused(tmp_path, body):
    raw = _group(tmp_path, "target", static=True, dropouts=())
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G  # the static arm passes
    _jump(raw, body, 1.01)
    # the jump is from the sample at t0 + 239/240 s = 13.496 s
    with pytest.raises(RecordingError, match=rf"at t=13\.496 s \(rule: {body} speed <= {MAX_SPEED[body]:g} m/s\)"):
        validate_group(raw, G, limits=LIMITS)


@pytest.mark.parametrize("body", sorted(MAX_SPEED))
def test_a_speed_just_under_each_body_limit_passes(tmp_path, body):
    raw = _group(tmp_path, "target", static=True, dropouts=())
    _jump(raw, body, 0.99)
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G


def test_the_limit_applies_across_a_dropout_to_the_next_tracked_sample(tmp_path):
    """Over a lost sample the speed is the displacement over both intervals: a jump of 1.5 x the
    one-interval limit spread over 2/240 s is 0.75 x the limit and passes; 2.5 x is refused."""
    for factor, ok in ((1.5, True), (2.5, False)):
        raw = _group(tmp_path / str(factor), static=True, dropouts=(("tip", 1.0, 1),))
        p = group_paths(raw, G)["mocap"]
        df = pd.read_parquet(p)
        k = int(round(1.0 * HZ))
        assert not df["tip_valid"].iloc[k] and df["tip_valid"].iloc[k - 1] and df["tip_valid"].iloc[k + 1]
        df.loc[df.index[k + 1 :], "tip_x"] += factor * MAX_SPEED["tip"] / HZ
        write_parquet(df, p)
        if ok:
            assert validate_group(raw, G, limits=LIMITS)["group_id"] == G
        else:
            with pytest.raises(RecordingError, match=r"rule: tip speed <= 10 m/s"):
                validate_group(raw, G, limits=LIMITS)



def test_a_body_tracked_in_two_samples_only_has_its_speed_checked(tmp_path):
    """Two tracked samples are the fewest that have a speed: a jump between them 1.01 x the limit
    is refused, 0.99 x passes (the gate's motion check alone, on a 2-sample recording)."""
    from embodied_snap.rawschema import TRACKED_BODIES
    from embodied_snap.validate import _check_motion

    t = np.array([T0, T0 + 1 / HZ])
    for factor, ok in ((0.99, True), (1.01, False)):
        mocap = {"t": t}
        for b in TRACKED_BODIES:
            mocap[f"{b}_valid"] = np.array([True, True])
            for c in "xyz":
                mocap[f"{b}_{c}"] = np.zeros(2)
        mocap["tip_x"] = np.array([0.0, factor * MAX_SPEED["tip"] / HZ])
        if ok:
            _check_motion(mocap, tmp_path / "mocap.parquet", G, LIMITS, False, (t[0], t[-1]))
        else:
            with pytest.raises(RecordingError, match=r"rule: tip speed <= 10 m/s"):
                _check_motion(mocap, tmp_path / "mocap.parquet", G, LIMITS, False, (t[0], t[-1]))


# --- tracking: a body's longest gap and the target's tracked share ---------------------------------


def _edit_mocap(raw, fn):
    p = group_paths(raw, G)["mocap"]
    df = fn(pd.read_parquet(p))
    write_parquet(df, p)


def _lose(df, body, first, n):
    """Samples first .. first+n-1 of `body` lost (NaN pose, as the exporter writes)."""
    rows = df.index[first : first + n]
    df.loc[rows, f"{body}_valid"] = False
    cols = [c for c in df.columns if c.startswith(f"{body}_") and not c.endswith("_valid")]
    df.loc[rows, cols] = np.nan
    return df


@pytest.mark.parametrize("body", ["base", "s1", "s2", "tip"])
def test_a_dropout_just_over_the_bridged_gap_is_refused(tmp_path, body):
    """config resample.max_gap_s = 0.1: n lost samples leave (n + 1) / 240 s between tracked ones.
    22 lost: 0.0958 s passes; 24 lost: 0.1042 s does not."""
    assert CONFIG["resample"]["max_gap_s"] == 0.1
    raw = _group(tmp_path / "ok", dropouts=())
    _edit_mocap(raw, lambda df: _lose(df, body, 300, 22))
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G
    raw = _group(tmp_path / "bad", dropouts=())
    _edit_mocap(raw, lambda df: _lose(df, body, 300, 24))
    # tracked at sample 299 (t0 + 299/240 = 13.746 s) and again at sample 324 (13.850 s)
    with pytest.raises(RecordingError, match=rf"{body} not tracked for 0\.104 s from t=13\.746 to t=13\.850 s "
                       r"\(rule: mocap dropout <= 0\.1 s\)"):
        validate_group(raw, G, limits=LIMITS)


@pytest.mark.parametrize("at", ["start", "end"])
def test_a_dropout_at_the_recordings_edge_counts_from_the_edge(tmp_path, at):
    """A gap at an edge is measured from the edge of the grid's span: losing the first (last) 30
    samples leaves 30/240 = 0.125 s untracked, refused at either edge."""
    raw = _group(tmp_path, dropouts=())
    n = 721
    _edit_mocap(raw, lambda df: _lose(df, "tip", 0 if at == "start" else n - 30, 30))
    with pytest.raises(RecordingError, match=r"tip not tracked for .*rule: mocap dropout <= 0\.1 s"):
        validate_group(raw, G, limits=LIMITS)


def test_the_target_must_be_tracked_in_half_the_samples(tmp_path):
    """config gate.min_target_valid_fraction = 0.5 of 721 samples: 361 tracked pass, 360 do not."""
    assert CONFIG["gate"]["min_target_valid_fraction"] == 0.5

    def every_other(k):
        def fn(df):
            lost = df.index[1::2][:k]  # k samples lost, spread out (no long gap)
            df.loc[lost, "target_valid"] = False
            df.loc[lost, [c for c in df.columns if c.startswith("target_") and c != "target_valid"]] = np.nan
            return df
        return fn

    raw = _group(tmp_path / "ok", "target", dropouts=())
    _edit_mocap(raw, every_other(360))
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G
    raw = _group(tmp_path / "bad", "target", dropouts=())
    _edit_mocap(raw, every_other(360))
    _edit_mocap(raw, lambda df: _lose(df, "target", 0, 1))  # sample 0: one more lost
    _refusal(raw, "mocap", "target tracked in 50% of samples", "target tracked >= 50%")  # 360/721 = 49.9 %


# --- the servo log: covers the mocap, no long gap -------------------------------------------------


def _edit_servo(raw, fn):
    p = group_paths(raw, G)["servo"]
    write_parquet(fn(pd.read_parquet(p)).reset_index(drop=True), p)


def test_the_servo_log_may_start_up_to_50_ms_after_the_mocap(tmp_path):
    """rawschema COVER_TOL_S = 0.05 s (the resampler's edge); fakerig's log starts 30 ms before."""
    raw = _group(tmp_path / "ok")
    _edit_servo(raw, lambda s: s[s.t >= T0 + 0.04])
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G
    raw = _group(tmp_path / "bad")
    _edit_servo(raw, lambda s: s[s.t >= T0 + 0.06])
    with pytest.raises(RecordingError, match=r"rule: servo log covers mocap"):
        validate_group(raw, G, limits=LIMITS)
    raw = _group(tmp_path / "end")
    _edit_servo(raw, lambda s: s[s.t <= T_END - 0.06])
    with pytest.raises(RecordingError, match=r"rule: servo log covers mocap"):
        validate_group(raw, G, limits=LIMITS)
    raw = _group(tmp_path / "end-ok")
    _edit_servo(raw, lambda s: s[s.t <= T_END - 0.04])
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G


def test_a_servo_gap_just_over_50_ms_is_refused(tmp_path):
    """config gate.max_servo_gap_s = 0.05: drop the servo samples inside a window, then the gap is
    the difference of the two samples either side of it, read off the log itself."""
    assert CONFIG["gate"]["max_servo_gap_s"] == 0.05
    for width, ok in ((0.02, True), (0.07, False)):
        raw = _group(tmp_path / str(width))
        s = pd.read_parquet(group_paths(raw, G)["servo"])
        a = T0 + 1.0
        keep = (s.t <= a) | (s.t >= a + width)
        gap = float(s.t[keep].diff().max())
        assert (gap <= 0.05) == ok
        _edit_servo(raw, lambda s, keep=keep: s[keep])
        if ok:
            assert validate_group(raw, G, limits=LIMITS)["group_id"] == G
        else:
            with pytest.raises(RecordingError, match=rf"no sync-read for {gap:.3f} s .*rule: servo log gap <= 0\.05 s"):
                validate_group(raw, G, limits=LIMITS)


# --- the whole message: file, group, what, rule ------------------------------------------------------


def _refusal(raw, kind, what, rule, limits=LIMITS):
    with pytest.raises(RecordingError) as e:
        validate_group(raw, G, limits=limits)
    assert str(e.value) == f"{group_paths(raw, G)[kind]}: group {G}: {what} (rule: {rule})"


def test_meta_refusals_name_the_file_the_group_and_the_rule(tmp_path):
    raw = _group(tmp_path / "a")
    no_dyn = replace(LIMITS, labels={k: v for k, v in LIMITS.labels.items() if not k.startswith("dynamics")})
    _refusal(raw, "meta", "no gate.labels entry for dynamics", "gate.labels names every evidence set", no_dyn)
    no_prog = replace(LIMITS, program={k: v for k, v in LIMITS.program.items() if k != "dynamics"})
    _refusal(raw, "meta", "no gate.program entry for dynamics", "gate.program names every evidence set", no_prog)
    _set_label(raw, "t_s1", None)
    _refusal(raw, "meta", "labels has no 't_s1' (dynamics/free_space needs snap_speed_event, t_preload, t_slack, "
             "t_s2, t_s1)", "labels complete per evidence set")
    raw = _group(tmp_path / "b")
    p = group_paths(raw, G)["meta"]
    write_json({**json.loads(p.read_text()), "labels": ["t_s1"]}, p)
    _refusal(raw, "meta", "'labels' missing or not an object", "labels complete per evidence set")


def test_a_hole_in_the_mocap_rows(tmp_path):
    """Rows missing altogether: 23 rows gone leave 24/240 = 0.1 s between samples, which passes (the
    limit is inclusive); 48 gone leave 49/240 = 0.204 s, refused with both ends of the hole."""
    raw = _group(tmp_path / "ok", dropouts=())
    _edit_mocap(raw, lambda df: df.drop(index=df.index[300:323]).reset_index(drop=True))
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G
    raw = _group(tmp_path / "bad", dropouts=())
    _edit_mocap(raw, lambda df: df.drop(index=df.index[300:348]).reset_index(drop=True))
    _refusal(raw, "mocap", "no sample for 0.204 s from t=13.746 to t=13.950 s", "mocap hole <= 0.1 s")


def test_a_dropout_of_exactly_the_bridged_gap_passes(tmp_path):
    raw = _group(tmp_path, dropouts=())
    _edit_mocap(raw, lambda df: _lose(df, "s2", 300, 23))  # tracked at 299 and 323: 24/240 = 0.1 s
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G


def test_a_body_never_tracked(tmp_path):
    raw = _group(tmp_path, dropouts=())
    _edit_mocap(raw, lambda df: _lose(df, "s1", 0, len(df)))
    _refusal(raw, "mocap", "s1 never tracked", "mocap dropout <= 0.1 s")


def test_the_servo_span_refusal_names_both_spans(tmp_path):
    raw = _group(tmp_path)
    _edit_servo(raw, lambda s: s[s.t >= T0 + 0.06])
    ts = pd.read_parquet(group_paths(raw, G)["servo"]).t
    _refusal(raw, "servo", f"servo log spans {ts.iloc[0]:.3f}..{ts.iloc[-1]:.3f} s, mocap 12.500..15.500 s",
             "servo log covers mocap")


# --- the schema's builders, on frames made here ----------------------------------------------------------


def _passes(checks, df):
    try:
        pa.DataFrameSchema(checks=checks).validate(df)
        return True
    except pa.errors.SchemaError:
        return False


def test_rate_check_accepts_the_rate_within_its_tolerance_inclusive():
    t = lambda step: pd.DataFrame({"t": np.arange(8) * step})  # noqa: E731
    assert _passes([RS._rate_check(240.0, 0.1, "r")], t(1 / 240))
    assert not _passes([RS._rate_check(240.0, 0.1, "r")], t(1 / 200))  # 20 % slow
    # binary-exact: a 0.625 s step at 2 Hz is 25 % off; a tolerance of 25 % includes it
    assert _passes([RS._rate_check(2.0, 0.25, "r")], t(0.625))
    assert not _passes([RS._rate_check(2.0, 0.24, "r")], t(0.625))
    assert not _passes([RS._rate_check(240.0, 0.1, "r")], t(1 / 240).iloc[:1])  # one sample: no rate


def test_body_checks_valid_samples_complete_and_unit_quaternions():
    cols = ["tip_x", "tip_y", "tip_z", "tip_qw", "tip_qx", "tip_qy", "tip_qz"]
    assert [f"tip_{f}" for f in RS.POSE_FIELDS] == cols
    ok = pd.DataFrame([[0.1, -0.5, 0.2, 1.0, 0.0, 0.0, 0.0, True],
                       [0.1, -0.5, 0.2, 0.5, 0.5, 0.5, 0.5, True],
                       [np.nan] * 7 + [False]], columns=cols + ["tip_valid"])
    assert _passes(RS._body_checks("tip"), ok)
    bad_nan = ok.copy()
    bad_nan.loc[0, "tip_y"] = np.nan
    assert not _passes(RS._body_checks("tip")[:1], bad_nan)
    tol = RS.QUAT_NORM_TOL
    long = ok.copy()
    long.loc[1, ["tip_qw", "tip_qx", "tip_qy", "tip_qz"]] = 0.5 * (1 + 2 * tol)  # norm 1 + 2 tol
    assert not _passes(RS._body_checks("tip")[1:], long)
    near = ok.copy()
    near.loc[1, ["tip_qw", "tip_qx", "tip_qy", "tip_qz"]] = 0.5 * (1 - 0.5 * tol)
    assert _passes(RS._body_checks("tip")[1:], near)


def test_a_fresh_mocap_schema_refuses_a_valid_sample_with_nan(tmp_path):
    raw = _group(tmp_path, dropouts=())
    df = pd.read_parquet(group_paths(raw, G)["mocap"])
    schema = RS.mocap_schema.__wrapped__()  # not the cached one
    schema.validate(df)
    df.loc[10, "base_qx"] = np.nan
    with pytest.raises(pa.errors.SchemaError):
        schema.validate(df)


# --- meta.json's identity fields: the fast path and the schema agree ----------------------------------


@pytest.mark.parametrize("key, value", [("session", ""), ("session", 5), ("group_id", None), ("category", "sweep"),
                                        ("evidence_set", "nonsense"), ("session", ["s01"])])
def test_a_bad_identity_field_in_meta_is_refused(tmp_path, key, value):
    raw = _group(tmp_path)
    p = group_paths(raw, G)["meta"]
    write_json({**json.loads(p.read_text()), key: value}, p)
    with pytest.raises(RecordingError, match=rf"^{p}: group {G}: "):
        validate_group(raw, G, limits=LIMITS)


def test_a_non_ascii_session_takes_the_schemas_path_and_passes(tmp_path):
    raw = _group(tmp_path)
    p = group_paths(raw, G)["meta"]
    meta = {**json.loads(p.read_text()), "session": "s01-Zürich"}
    write_json(meta, p)
    assert not RS._meta_passes(meta)  # the fast path leaves it to pandera
    assert validate_group(raw, G, limits=LIMITS)["session"] == "s01-Zürich"


def test_dropout_and_speed_refusals_name_the_file_and_the_group(tmp_path):
    raw = _group(tmp_path / "drop", dropouts=())
    _edit_mocap(raw, lambda df: _lose(df, "tip", 300, 24))
    _refusal(raw, "mocap", "tip not tracked for 0.104 s from t=13.746 to t=13.850 s", "mocap dropout <= 0.1 s")
    raw = _group(tmp_path / "fast", static=True, dropouts=())
    _jump(raw, "tip", 1.01)  # 1.01 * 10 m/s over 1/240 s: 0.042 m in 0.0042 s
    _refusal(raw, "mocap", "tip moves 0.042 m in 0.0042 s (10.1 m/s) at t=13.496 s", "tip speed <= 10 m/s")


def test_outcome_labels_are_booleans_and_other_labels_are_free(tmp_path):
    raw = _group(tmp_path)
    _set_label(raw, "operator_note", "re-taped S2")  # neither a time nor an outcome: not checked
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G
    for key, value in (("attached", "yes"), ("snap_speed_event", 1), ("retrieved", None)):
        raw = _group(tmp_path / key)
        _set_label(raw, key, value)
        _refusal(raw, "meta", f"label {key}={value!r} is not true/false", "outcome labels are booleans")


# --- a refusal names its rule and says what failed (the schema's checks, called directly) -----------


def _failed_check(checks, df):
    with pytest.raises(pa.errors.SchemaError) as e:
        pa.DataFrameSchema(checks=checks).validate(df)
    return e.value.check.name, e.value.check.error


def test_the_body_checks_name_their_rule_and_what_failed():
    """The rule names are docs/data.md's ("valid <body> samples complete", "unit <body> quaternions");
    the refusal line prints the name as its rule and the error as what failed."""
    cols = [f"s2_{f}" for f in ("x", "y", "z", "qw", "qx", "qy", "qz")]
    ok = pd.DataFrame([[0.1, -0.5, 0.2, 1.0, 0.0, 0.0, 0.0, True]] * 2, columns=cols + ["s2_valid"])
    nan = ok.copy()
    nan.loc[1, "s2_z"] = np.nan
    assert _failed_check(RS._body_checks("s2"), nan) == (
        "valid s2 samples complete", "s2 marked valid but its pose has NaN/inf")
    twice = ok.copy()
    twice.loc[1, "s2_qw"] = 2.0
    assert _failed_check(RS._body_checks("s2"), twice) == (
        "unit s2 quaternions", f"s2 quaternion norm differs from 1 by more than {RS.QUAT_NORM_TOL:g}")


def test_the_rate_check_names_its_rule_and_the_rate():
    slow = pd.DataFrame({"t": np.arange(8) / 200.0})
    assert _failed_check([RS._rate_check(240.0, 0.1, "mocap at 240 Hz")], slow) == (
        "mocap at 240 Hz", "median sample interval is not 1/240 s (+-10%)")


def test_two_samples_at_the_rate_have_a_rate():
    assert _passes([RS._rate_check(240.0, 0.1, "r")], pd.DataFrame({"t": [0.0, 1 / 240]}))


def _servo_times(raw, first, last):
    """The servo log cut to [first, last] s, its first and last sample moved onto those times."""
    def cut(s):
        s = s[(s.t >= first - 0.01) & (s.t <= last + 0.01)].copy()
        s.iloc[0, s.columns.get_loc("t")], s.iloc[-1, s.columns.get_loc("t")] = first, last
        return s
    _edit_servo(raw, cut)


def test_the_servo_cover_counts_from_the_first_and_last_mocap_sample(tmp_path):
    """The log must start by 50 ms after the mocap's first sample and end by 50 ms before its last
    (rawschema COVER_TOL_S): 52 ms is refused though it lies within 50 ms of the second sample
    (12.5 + 1/240 s) or of the second-last one."""
    raw = _group(tmp_path / "start")
    _servo_times(raw, T0 + 0.052, T_END)
    _refusal(raw, "servo", f"servo log spans {T0 + 0.052:.3f}..{T_END:.3f} s, mocap {T0:.3f}..{T_END:.3f} s",
             "servo log covers mocap")
    raw = _group(tmp_path / "end")
    _servo_times(raw, T0, T_END - 0.052)
    _refusal(raw, "servo", f"servo log spans {T0:.3f}..{T_END - 0.052:.3f} s, mocap {T0:.3f}..{T_END:.3f} s",
             "servo log covers mocap")


def test_the_servo_gap_refusal_names_the_file_the_group_and_the_rule(tmp_path):
    raw = _group(tmp_path)
    s = pd.read_parquet(group_paths(raw, G)["servo"])
    keep = (s.t <= T0 + 1.0) | (s.t >= T0 + 1.07)
    a, b = float(s.t[keep & (s.t <= T0 + 1.0)].max()), float(s.t[keep & (s.t >= T0 + 1.07)].min())
    _edit_servo(raw, lambda s: s[keep])
    _refusal(raw, "servo", f"no sync-read for {b - a:.3f} s from t={a:.3f} to t={b:.3f} s", "servo log gap <= 0.05 s")


def test_more_meta_refusals_name_the_file_the_group_and_the_rule(tmp_path):
    """The label-time and format-version refusals, whole; the rule texts are docs/data.md's."""
    raw = _group(tmp_path / "a")
    _set_label(raw, "t_s1", T_END + 0.001)
    _refusal(raw, "meta", "label t_s1=15.501 is not a time in 12.500..15.500 s", "label times inside the recording")
    raw = _group(tmp_path / "b")
    p = group_paths(raw, G)["meta"]
    write_json({**json.loads(p.read_text()), "format_version": 2}, p)
    _refusal(raw, "meta", "format_version 2; this pipeline reads 1", "format version 1")


def test_a_category_entry_overrides_its_sets_labels(tmp_path):
    """config gate.labels: dynamics/target needs `attached`, which plain dynamics does not."""
    assert "attached" in CONFIG["gate"]["labels"]["dynamics/target"]
    assert "attached" not in CONFIG["gate"]["labels"]["dynamics"]
    raw = _group(tmp_path, category="target")
    _set_label(raw, "attached", None)
    _refusal(raw, "meta", "labels has no 'attached' (dynamics/target needs "
             + ", ".join(CONFIG["gate"]["labels"]["dynamics/target"]) + ")", "labels complete per evidence set")


def test_positions_of_bodies_never_tracked_are_within_any_limit():
    """The fast path's distance-from-the-base check on a frame with no tracked position at all
    (every body lost): nothing is out of range, so the dropout rule, not a crash, refuses the
    recording; tracked, the limit itself passes and a millimetre past it does not."""
    from embodied_snap.rawformat import BODIES, mocap_columns

    cols = {"t": np.arange(10) / 240.0}
    for b in BODIES:
        cols.update({f"{b}_{f}": np.full(10, np.nan) for f in ("x", "y", "z", "qw", "qx", "qy", "qz")})
        cols[f"{b}_valid"] = np.zeros(10, bool)
    lost = pd.DataFrame(cols)[mocap_columns()]
    assert RS._mocap_passes(lost)
    tracked = lost.copy()
    for b in ("base", "tip"):
        tracked[[f"{b}_{f}" for f in ("x", "y", "z", "qw", "qx", "qy", "qz")]] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
        tracked[f"{b}_valid"] = True
    tracked["tip_y"] = -RS.MAX_FROM_BASE_M
    assert RS._mocap_passes(tracked)
    assert not RS._mocap_passes(tracked.assign(tip_y=-RS.MAX_FROM_BASE_M - 0.001))
