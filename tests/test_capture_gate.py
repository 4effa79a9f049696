"""What the gate asks of a recording a lab brings (embodied_snap/rawschema.py): the unit rule stated in
the arm's own frame, float32 columns, and a log too short to have a rate.

Groups are fakerig's (tests/fakerig.py), edited as a lab's exporter would have written them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from embodied_snap import rawschema as RS
from embodied_snap.characterize.load import group as load_group
from embodied_snap.io import write_parquet
from embodied_snap.rawformat import BODIES, group_paths
from embodied_snap.resample import resample_group
from embodied_snap.validate import RecordingError, validate_group

from fakerig import BASE_POS, write_fake_raw
from paper_protocol import LIMITS

G = "dyn_0001"
POSITIONS = [f"{b}_{a}" for b in BODIES for a in "xyz"]


@pytest.fixture
def raw(tmp_path):
    raw = tmp_path / "raw_data"
    write_fake_raw(raw, (G,))
    return raw


def edit_mocap(raw, fn):
    p = group_paths(raw, G)["mocap"]
    write_parquet(fn(pd.read_parquet(p)), p)
    return p


def refused(raw):
    with pytest.raises(RecordingError) as e:
        validate_group(raw, G, limits=LIMITS)
    assert "\n" not in str(e.value)
    return e.value


def schema_passes(df):
    import pandera.errors as pe

    try:
        RS.mocap_schema().validate(df)
        return True
    except (pe.SchemaError, pe.SchemaErrors):
        return False


# --- the unit rule, in the base's frame ------------------------------------------------------------


def test_an_arm_far_from_the_capture_origin_passes(raw):
    # the base 5.48 m from the origin (a volume whose origin is on the far wall): the arm is as it was
    shift = np.array([5.48, 0.0, 0.0]) - np.asarray(BASE_POS) * [1, 0, 0]
    p = edit_mocap(raw, lambda m: m.assign(**{f"{b}_{a}": m[f"{b}_{a}"] + shift[i] for b in BODIES
                                              for i, a in enumerate("xyz")}))
    m = pd.read_parquet(p)
    assert np.linalg.norm(m.loc[0, ["base_x", "base_y", "base_z"]].to_numpy(float)) > 5.48
    assert validate_group(raw, G, limits=LIMITS)["group_id"] == G
    assert RS._mocap_passes(m) and schema_passes(m)  # the fast path and the schema agree


def test_positions_in_millimetres_are_refused_by_the_distance_from_the_base(raw):
    p = edit_mocap(raw, lambda m: m.assign(**{c: m[c] * 1000 for c in POSITIONS}))
    e = refused(raw)
    assert e.rule == "bodies within 2 m of the base" == RS.FROM_BASE_RULE
    assert str(e).startswith(f"{p}: group {G}: s1 farther than 2 m from the base")
    assert not RS._mocap_passes(pd.read_parquet(p))


def test_a_body_far_from_the_base_is_refused_where_both_are_tracked(raw):
    """The tip 2.5 m from the base: on the base's own dropout frames the rule has no base to measure
    from and says nothing (the speed rule, later, would); on every frame, it refuses."""
    p = group_paths(raw, G)["mocap"]
    m = pd.read_parquet(p)
    lost = ~m.base_valid.to_numpy()
    assert lost.any() and m.tip_valid[lost].any()
    there = m.assign(tip_x=np.where(lost, m.tip_x + 2.5, m.tip_x))
    RS.check_mocap(there, p, G)
    assert RS._mocap_passes(there) and schema_passes(there)  # the fast path and the schema agree
    everywhere = m.assign(tip_x=m.tip_x + 2.5)
    with pytest.raises(RecordingError) as e:
        RS.check_mocap(everywhere, p, G)
    assert e.value.rule == RS.FROM_BASE_RULE
    assert e.value.what.startswith("tip farther than 2 m from the base (positions not in metres?) at row 0")
    assert not RS._mocap_passes(everywhere) and not schema_passes(everywhere)


# --- float32 columns --------------------------------------------------------------------------------


def test_float32_mocap_columns_are_read_as_float64(raw, tmp_path):
    p = group_paths(raw, G)["mocap"]
    m = pd.read_parquet(p)
    floats = [c for c in m if m[c].dtype == np.float64]
    write_parquet(m.astype(dict.fromkeys(floats, np.float32)), p)
    assert pd.read_parquet(p)["t"].dtype == np.float32  # as the exporter wrote it
    entry = validate_group(raw, G, limits=LIMITS)
    assert entry["n_mocap"] == len(m)
    # the jobs read them as a tree holding the same values in float64 would: the fits' loader casts,
    # and resampling's arithmetic on float32 times is exact (neighbours differ exactly)
    wide = tmp_path / "wide"
    write_fake_raw(wide, (G,))
    write_parquet(pd.read_parquet(p).astype(dict.fromkeys(floats, np.float64)), group_paths(wide, G)["mocap"])
    pd.testing.assert_frame_equal(resample_group(raw, G, 50.0, 0.1), resample_group(wide, G, 50.0, 0.1))
    mocap, _, _ = load_group(raw, G)
    pd.testing.assert_frame_equal(mocap, load_group(wide, G)[0])


# --- a log without an interval --------------------------------------------------------------------


@pytest.mark.parametrize("rows, what", [(0, "empty: no rows"), (1, "one row: no interval between samples")])
def test_a_mocap_log_of_0_or_1_rows_says_so(raw, rows, what):
    p = edit_mocap(raw, lambda m: m.iloc[:rows])
    e = refused(raw)
    assert str(e) == f"{p}: group {G}: {what} (rule: a log holds at least 2 samples)"


def test_a_servo_log_of_1_row_says_so(raw):
    p = group_paths(raw, G)["servo"]
    write_parquet(pd.read_parquet(p).iloc[:1], p)
    what = "one row: no interval between samples"
    assert str(refused(raw)) == f"{p}: group {G}: {what} (rule: a log holds at least 2 samples)"
