"""The capture-format readers (embodied_snap.capture) against real exports, small broken ones, and
the rigid fit.

The expected values of the real files are literals read by hand from the files (the line and
cells are named in each comment), never values computed by the reader under test or by ezc3d.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from embodied_snap.capture.c3d import read_c3d
from embodied_snap.capture.errors import CaptureError
from embodied_snap.capture.motive import read_motive_csv
from embodied_snap.capture.rigid import fit_pose

LABFORMATS = Path(__file__).resolve().parents[2] / "shared" / "labformats"


@pytest.fixture
def lab():
    if not LABFORMATS.is_dir():
        pytest.skip("the real capture exports are not on this machine")
    return LABFORMATS


def xyz(df, i):
    return df.loc[i, ["x", "y", "z"]].to_numpy(float)


def quat(df, i):
    return df.loc[i, ["qw", "qx", "qy", "qz"]].to_numpy(float)


# --- Motive CSV: the real exports --------------------------------------------------------------


def test_motive_rigid_body_with_quality_columns(lab):
    take = read_motive_csv(lab / "motive123_m_rigidbody_mme_markerquality_120hz.csv")
    assert (take.version, take.rate_hz, take.units, take.space) == ("1.23", 120.0, "Meters", "Global")
    assert len(take.frame) == take.total_frames == 499
    body = take.rigid_bodies["ernesto_body"]
    # line 8 (frame 0), cells 3-9: Rotation X, Y, Z, W, Position X, Y, Z
    assert quat(body, 0) == pytest.approx([-0.760444, -0.008570, -0.649345, -0.001615])
    assert xyz(body, 0) == pytest.approx([3.717927, 0.045963, -2.209530])
    # Mean Marker Error and Marker Quality are not data columns
    assert list(body.columns) == ["x", "y", "z", "qw", "qx", "qy", "qz", "valid"]
    # line 12 (frame 4): the rigid body and its Rigid Body Markers are blank, the Markers are not
    assert not body.valid[4] and body.valid.sum() == 498
    assert not take.body_markers["ernesto_body:Marker1"].valid[4]
    assert take.markers["ernesto_body:Marker1"].valid[4]
    # one name, two columns types: line 8 cells 11-13 (Rigid Body Marker) and 27-29 (Marker)
    assert xyz(take.body_markers["ernesto_body:Marker1"], 0) == pytest.approx([3.833308, 0.032543, -2.237125])
    assert xyz(take.markers["ernesto_body:Marker1"], 0) == pytest.approx([3.833445, 0.032409, -2.237666])
    assert len(take.markers) == len(take.body_markers) == 4


def test_motive_quaternion_sign_flip_is_kept_as_exported(lab):
    take = read_motive_csv(lab / "motive123_m_single_rigidbody_240hz.csv")
    assert (take.rate_hz, take.units, len(take.frame)) == (240.0, "Meters", 10460)
    body = take.rigid_bodies["RigidBody"]
    # lines 8 and 9: X, Y, Z, W of frames 0 and 1, nearly q and -q
    assert quat(body, 0) == pytest.approx([-0.163966, 0.715879, 0.252092, -0.630144])
    assert quat(body, 1) == pytest.approx([0.164013, -0.715889, -0.252145, 0.630100])
    assert np.dot(quat(body, 0), quat(body, 1)) == pytest.approx(-1, abs=1e-6)
    assert xyz(body, 0) == pytest.approx([0.047597, 0.607298, 0.329784])
    assert body.valid.all()
    # the last line: frame 10459 at 43.579167 s
    assert (take.frame[-1], take.t[-1]) == (10459, pytest.approx(43.579167))


def test_motive_labelled_markers_in_millimetres_at_30_hz(lab):
    take = read_motive_csv(lab / "motive123_mm_labeled_markers_30hz.csv")
    # 30 Hz is outside the rig's rates: reported, not refused (the importer decides)
    assert (take.rate_hz, take.units, len(take.frame)) == (30.0, "Millimeters", 2032)
    assert take.rigid_bodies == {} and len(take.markers) == 11
    # line 8, cells 3-5, in mm
    cmc = take.markers["Ard_her_20-317L_4jt7wing:cmc"]
    assert xyz(cmc, 0) == pytest.approx([0.107554214, 0.208315002, -0.003679659])
    # line 297 (frame 289): cells 15-17 (humerus_leading) blank; 104 of the 2032 rows are
    humerus = take.markers["Ard_her_20-317L_4jt7wing:humerus_leading"]
    assert not humerus.valid[289] and np.isnan(xyz(humerus, 289)).all()
    assert humerus.valid.sum() == 2032 - 104


def test_motive_unlabelled_markers_with_millisecond_times_and_a_hungarian_start_time(lab):
    take = read_motive_csv(lab / "motive123_mm_unlabeled_markers_360hz.csv")  # LF line endings
    assert take.start_time == "2023-11-28 10.27.58.765 DU."  # "DU." is Hungarian for PM
    assert (take.rate_hz, take.units, len(take.frame)) == (360.0, "Millimeters", 1353)
    # line 9: the Time column says 0.003, rounded to 1 ms; the clock is Frame / rate, 1/360 s
    assert take.t[1] == 1 / 360 and take.t[-1] == 1352 / 360
    assert list(take.markers) == [f"Unlabeled {n}" for n in range(1036, 1054)]
    # line 8, cells 3-5
    assert xyz(take.markers["Unlabeled 1036"], 0) == pytest.approx([2.659741943, -0.830793884, -2.862191650])
    # cells 48-50 (Unlabeled 1051): trailing empty cells up to line 355 (frame 347), then line 356
    late = take.markers["Unlabeled 1051"]
    assert not late.valid[:348].any() and late.valid[348]
    assert xyz(late, 348) == pytest.approx([0.440624146, 1.471550049, 1.803150757])


def test_the_360_hz_nmotive_export_keeps_a_constant_360_hz_clock(lab):
    from embodied_snap.rawschema import _mocap_intervals_constant, _mocap_rate_in_range

    path = lab / "motive123_mm_unlabeled_markers_360hz.csv"
    take = read_motive_csv(path)
    # its Time column steps 3, 3, 2, 3, ... ms (rounded): as a clock, intervals of 2 and 3 ms are no
    # whole number of their median and the gate's constant-rate rule refuses it; Frame / 360 is exact
    time = pd.read_csv(path, skiprows=7, header=None)[1].to_numpy(float)
    assert list(time[:4]) == [0.0, 0.003, 0.006, 0.008] and not _mocap_intervals_constant(time)
    assert np.diff(take.t) == pytest.approx(np.full(1352, 1 / 360), abs=1e-12)
    assert _mocap_intervals_constant(take.t) and _mocap_rate_in_range(take.t)


def shifted_time(src, dst, row, seconds):
    """A copy of a Motive export with one data row's Time cell (its second) moved by `seconds`."""
    lines = src.read_bytes().decode().split("\n")
    axis = next(i for i, ln in enumerate(lines) if ln.startswith("Frame,"))
    cells = lines[axis + 1 + row].split(",")
    cells[1] = f"{float(cells[1]) + seconds:.6f}"
    lines[axis + 1 + row] = ",".join(cells)
    dst.write_bytes("\n".join(lines).encode())
    return dst


def test_a_time_column_more_than_half_a_millisecond_off_is_refused(lab, tmp_path):
    # frame 1 of the 360 Hz export: Time 0.003 is 0.222 ms from 1/360 s; 0.004 is 1.222 ms from it
    path = shifted_time(lab / "motive123_mm_unlabeled_markers_360hz.csv", tmp_path / "t.csv", 1, 0.001)
    with pytest.raises(CaptureError) as e:
        read_motive_csv(path)
    assert str(e.value) == (f"{path}: frame 1: the Time column says 0.004000 s, Frame / Export Frame Rate "
                            "0.002778 s (1.222 ms apart) (rule: Time is Frame / Export Frame Rate to within 0.5 ms)")


def test_time_rounded_to_the_millisecond_at_its_worst_still_reads(lab, tmp_path):
    # The 240 Hz export with Time rounded to 1 ms as NMotive writes it, every exact half (frames
    # 3, 9, 15, ...: 12.5, 37.5 ms) rounded down: half a millisecond off, the most rounding leaves
    src = lab / "motive123_m_single_rigidbody_240hz.csv"
    lines = src.read_bytes().decode().split("\n")
    axis = next(i for i, ln in enumerate(lines) if ln.startswith("Frame,"))
    for i in range(axis + 1, len(lines)):
        if lines[i].strip():
            cells = lines[i].split(",")
            sixths = int(cells[0]) * 25  # frame / 240 s in sixths of a millisecond
            ms = sixths // 6 if sixths % 6 == 3 else (sixths + 2) // 6
            cells[1] = f"{ms / 1e3:.3f}"
            lines[i] = ",".join(cells)
    path = tmp_path / "ms.csv"
    path.write_bytes("\n".join(lines).encode())
    assert lines[axis + 4].startswith("3,0.012,")
    take = read_motive_csv(path)
    assert take.t[3] == 3 / 240 and len(take.t) == 10460


def test_a_take_in_local_coordinates_is_refused_with_the_reason(lab, tmp_path):
    src = (lab / "motive123_m_rigidbody_mme_markerquality_120hz.csv").read_bytes()
    assert src.count(b"Coordinate Space,Global") == 1
    path = tmp_path / "local.csv"
    path.write_bytes(src.replace(b"Coordinate Space,Global", b"Coordinate Space,Local"))
    with pytest.raises(CaptureError) as e:
        read_motive_csv(path)
    assert str(e.value) == (f"{path}: Coordinate Space 'Local': a Local take puts each bone relative to its "
                            "parent, not in the capture volume (rule: Coordinate Space Global (export with "
                            "world coordinates))")


def test_motive_timecode_column_in_centimetres(lab):
    take = read_motive_csv(lab / "motive124_cm_timecode_markers_120hz_EXCERPT40.csv")
    assert (take.version, take.rate_hz, take.units) == ("1.24", 120.0, "Centimeters")
    # an excerpt: 40 rows of the 8622 its header declares, read as they are
    assert (len(take.frame), take.total_frames) == (40, 8622)
    # line 8, cell 3, and line 47 (frame 39)
    assert take.timecode[0] == "15:26:46:12.02" and take.timecode[-1] == "15:26:46:22.01"
    # line 8, cells 4-6, in cm
    assert xyz(take.markers["Oak-D-Kamera:Marker 001"], 0) == pytest.approx([-0.92003639, 3.11561951, 1.34137253])
    assert not take.markers["Unlabeled 1189"].valid.any()  # blank throughout
    assert len(take.markers) == 4


# --- Motive CSV: small exports written here ----------------------------------------------------

META = {
    "Format Version": "1.23",
    "Take Name": "small",
    "Take Notes": "",
    "Capture Frame Rate": "100.000000",
    "Export Frame Rate": "100.000000",
    "Capture Start Time": "2024-03-01 02.15.00.000 PM",
    "Total Frames in Take": "3",
    "Total Exported Frames": "3",
    "Rotation Type": "Quaternion",
    "Length Units": "Millimeters",
    "Coordinate Space": "Global",
}
# (Type, Name, ID, component, axis)
BODY = [("Rigid Body", "arm", "A1", "Rotation", a) for a in "XYZW"] + [
    ("Rigid Body", "arm", "A1", "Position", a) for a in "XYZ"
]
MARKER = [("Marker", "arm:Marker1", "B2", "Position", a) for a in "XYZ"]
# frame, time, then arm's X, Y, Z, W, x, y, z (mm), then the marker (mm; frame 1 occluded)
ROWS = [
    ["0", "0.000000", "0.0", "0.0", "0.0", "1.0", "10.0", "20.0", "30.0", "11.0", "21.0", "31.0"],
    ["1", "0.010000", "0.0", "0.6", "0.0", "0.8", "12.0", "20.0", "30.0", "", "", ""],
    ["2", "0.020000", "0.0", "0.8", "0.0", "0.6", "14.0", "20.0", "30.0", "15.0", "21.0", "31.0"],
]


def export(tmp_path, meta=META, columns=BODY + MARKER, rows=ROWS, eol="\r\n", parent=False, end=None):
    """A Motive CSV as Motive lays it out, from its metadata, column headers and rows."""
    header = [
        ",Type," + ",".join(c[0] for c in columns),
        ",Name," + ",".join(c[1] for c in columns),
        ",ID," + ",".join(c[2] for c in columns),
    ]
    if parent:
        header.append(",Parent," + ",".join("" for _ in columns))
    header += [",," + ",".join(c[3] for c in columns), "Frame,Time (Seconds)," + ",".join(c[4] for c in columns)]
    lines = [",".join(f"{k},{v}" for k, v in meta.items()), "", *header, *(",".join(r) for r in rows)]
    text = eol.join(lines) + eol
    path = tmp_path / "take.csv"
    path.write_text(text if end is None else text[:end], newline="")
    return path


@pytest.mark.parametrize("eol", ["\r\n", "\n"])
def test_small_export_reads_alike_with_crlf_and_lf(tmp_path, eol):
    take = read_motive_csv(export(tmp_path, eol=eol))
    arm = take.rigid_bodies["arm"]
    assert quat(arm, 1) == pytest.approx([0.8, 0.0, 0.6, 0.0])  # X, Y, Z, W -> w, x, y, z
    assert xyz(arm, 1) == pytest.approx([0.012, 0.020, 0.030])
    marker = take.markers["arm:Marker1"]
    assert list(marker.valid) == [True, False, True]
    assert list(take.frame) == [0, 1, 2] and take.timecode is None and take.name == "small"


def test_a_parent_row_and_tags_in_the_first_cell_are_found_by_their_tag(tmp_path):
    path = export(tmp_path, meta=META | {"Format Version": "1.25"}, parent=True)
    text = path.read_text().replace("\n,Type,", "\nType,,").replace("\n,Parent,", "\nParent,,")
    path.write_text(text)
    take = read_motive_csv(path)
    assert xyz(take.rigid_bodies["arm"], 2) == pytest.approx([0.014, 0.020, 0.030])


def without(meta, key):
    return {k: v for k, v in meta.items() if k != key}


@pytest.mark.parametrize(
    "meta, rule",
    [
        (without(META, "Format Version"), r"its first cell is not 'Format Version' \(rule: a Motive export opens"),
        (META | {"Format Version": "1.1"}, r"format version '1\.1' \(rule: Motive format version 1\.21-1\.25\)"),
        (META | {"Rotation Type": "XYZ"}, r"rotation type 'XYZ' \(rule: rotation type Quaternion\)"),
        (without(META, "Length Units"), r"no Length Units in the metadata row \(rule: length units given\)"),
        (META | {"Length Units": "Inches"}, r"length units 'Inches' \(rule: length units Millimeters"),
        (META | {"Export Frame Rate": "200.000000"}, r"frame 1: the Time column says 0\.010000 s, Frame / Export "
         r"Frame Rate 0\.005000 s \(5\.000 ms apart\) \(rule: Time is Frame / Export Frame Rate to within 0\.5 ms\)"),
    ],
    ids=["no-format-version", "version", "euler", "no-units", "inches", "rate-vs-time"],
)
def test_metadata_that_is_refused(tmp_path, meta, rule):
    with pytest.raises(CaptureError, match=rule):
        read_motive_csv(export(tmp_path, meta=meta))


def test_a_rigid_body_named_twice_is_refused(tmp_path):
    second = [(t, n, "C3", c, a) for t, n, _, c, a in BODY]
    rows = [r + r[2:9] for r in ROWS]
    with pytest.raises(CaptureError, match=r"Rigid Body 'arm' appears twice \(a second .*\) \(rule: each body"):
        read_motive_csv(export(tmp_path, columns=BODY + MARKER + second, rows=rows))


def test_an_unknown_column_type_is_refused(tmp_path):
    other = [("Trained Markerset", "m", "D4", "Position", a) for a in "XYZ"]
    rows = [r + ["1", "2", "3"] for r in ROWS]
    with pytest.raises(CaptureError, match=r"column type 'Trained Markerset' \(rule: column types "):
        read_motive_csv(export(tmp_path, columns=BODY + MARKER + other, rows=rows))


@pytest.mark.parametrize(
    "order, rule",
    [
        ([0, 2, 1], r"frames out of order: frame 1 after frame 2 \(rule: frames in order, each once\)"),
        ([0, 1, 1], r"frame 1 is duplicated \(rule: frames in order, each once\)"),
    ],
    ids=["out-of-order", "duplicated"],
)
def test_frames_out_of_order_or_duplicated_are_refused(tmp_path, order, rule):
    with pytest.raises(CaptureError, match=rule):
        read_motive_csv(export(tmp_path, rows=[ROWS[i] for i in order]))


def test_a_last_row_with_fewer_cells_is_truncated(tmp_path):
    rows = ROWS[:2] + [ROWS[2][:8]]  # cut after a cell, line break kept
    with pytest.raises(CaptureError, match=r"truncated: line 10 has 8 of the header's 12 cells \(rule: a complete"):
        read_motive_csv(export(tmp_path, rows=rows))


def test_a_last_row_cut_mid_cell_is_truncated(tmp_path):
    # every cell there, the last one cut short: only the missing line break shows it
    with pytest.raises(CaptureError, match=r"the last row does not end with a line break \(rule: a complete file\)"):
        read_motive_csv(export(tmp_path, end=-3))


def test_the_message_is_one_line_naming_the_file(tmp_path):
    path = export(tmp_path, meta=META | {"Rotation Type": "XYZ"})
    with pytest.raises(CaptureError) as e:
        read_motive_csv(path)
    assert str(e.value).startswith(str(path)) and "\n" not in str(e.value)


# --- C3D --------------------------------------------------------------------------------------


def test_c3d_vicon(lab):
    take = read_c3d(lab / "ezc3d_Vicon.c3d")
    assert (take.rate_hz, take.first_frame, take.units) == (100.0, 1, "mm")
    assert len(take.t) == 580 and len(take.markers) == 51
    # printed once by hand in a shell: ezc3d.c3d(...)["data"]["points"][:3, 0, 0], in mm
    assert xyz(take.markers["boite:gauche_ext"], 0) == pytest.approx([0.04416279, -0.27686194, 0.67569684], abs=1e-7)
    # printed the same way: its residual is -1 at frames 206 and 207; 305 samples in all
    assert not take.markers["boite:gauche_ext"].valid[206]
    assert sum((~m.valid).sum() for m in take.markers.values()) == 305


def test_c3d_qualisys(lab):
    take = read_c3d(lab / "ezc3d_Qualisys.c3d")
    # the header's first frame (word 4) is 705; a negative POINT:SCALE (float storage)
    assert (take.rate_hz, take.first_frame, take.units) == (200.0, 705, "mm")
    assert len(take.t) == 340 and len(take.markers) == 55 and take.t[1] == pytest.approx(0.005)
    # printed once by hand in a shell: ezc3d.c3d(...)["data"]["points"][:3, 0, 0], in mm
    assert xyz(take.markers["L_IAS"], 0) == pytest.approx([-0.22012262, 0.30642480, 0.84633612], abs=1e-7)
    assert all(m.valid.all() for m in take.markers.values())


def test_a_truncated_c3d_is_refused(lab, tmp_path):
    # ezc3d reads the frames a cut file holds and corrects its header to match: the file's own
    # header (words 4 and 5) still declares frames 1-580
    path = tmp_path / "cut.c3d"
    path.write_bytes((lab / "ezc3d_Vicon.c3d").read_bytes()[:200_000])
    with pytest.raises(CaptureError) as e:
        read_c3d(path)
    assert str(e.value) == (f"{path}: truncated: its header declares 580 frames (1-580), the file holds 48 "
                            "(rule: a complete file)")


def small_c3d(tmp_path, labels, units="mm"):
    ezc3d = pytest.importorskip("ezc3d")
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100]
    c["parameters"]["POINT"]["UNITS"]["value"] = [units]
    c["parameters"]["POINT"]["LABELS"]["value"] = labels
    c["data"]["points"] = np.ones((4, len(labels), 10))
    c.write(str(tmp_path / "small.c3d"))
    return tmp_path / "small.c3d"


def test_a_small_c3d_reads(tmp_path):
    take = read_c3d(small_c3d(tmp_path, ["a", "b"], units="cm"))
    assert list(take.markers) == ["a", "b"] and xyz(take.markers["b"], 9) == pytest.approx([0.01] * 3)


@pytest.mark.parametrize(
    "labels, units, rule",
    [
        ([], "mm", r"no point labels \(POINT:LABELS is empty\) \(rule: markers are named by POINT:LABELS\)"),
        (["a", "a"], "mm", r"point label 'a' appears twice \(rule: each marker named once\)"),
        (["a"], "in", r"POINT:UNITS 'in' \(rule: length units mm, cm or m\)"),
    ],
    ids=["no-labels", "label-twice", "inches"],
)
def test_c3d_that_is_refused(tmp_path, labels, units, rule):
    with pytest.raises(CaptureError, match=rule):
        read_c3d(small_c3d(tmp_path, labels, units))


# --- the rigid fit -----------------------------------------------------------------------------

LAYOUT = np.array([[0.0, 0.0, 0.0], [0.10, 0.0, 0.0], [0.0, 0.06, 0.0], [0.03, 0.02, 0.05]])


def place(layout, rotation, p):
    return np.einsum("nij,kj->nki", rotation.as_matrix(), layout) + p[:, None]


def test_the_fit_residual_is_the_rms_miss_of_an_independent_kabsch_fit():
    """Markers off their layout by unequal offsets, one frame with a marker occluded: the residual
    is the RMS distance of the seen markers from scipy's own best rigid fit (align_vectors), with
    the translation matching the centroids; a noiseless frame reads 0."""
    r = Rotation.from_rotvec([[0.4, -0.9, 1.7], [-1.1, 0.2, 0.5], [0.0, 0.7, -0.3]])
    p = np.array([[0.6, 1.1, -0.3], [-0.2, 0.9, 0.4], [0.1, 1.0, 0.2]])
    obs = place(LAYOUT, r, p)
    obs[0] += [[0.004, -0.002, 0.001], [0.0, 0.003, 0.0], [-0.005, 0.0, 0.002], [0.001, 0.001, -0.003]]
    obs[1] += [[0.0, 0.0, 0.006], [0.002, -0.004, 0.0], [np.nan] * 3, [-0.003, 0.002, 0.001]]
    _, _, valid, residual = fit_pose(LAYOUT, obs)
    assert valid.all()
    for n in (0, 1):
        seen = np.isfinite(obs[n]).all(axis=1)
        a, b = LAYOUT[seen], obs[n][seen]
        rot, _ = Rotation.align_vectors(b - b.mean(0), a - a.mean(0))
        miss = rot.apply(a - a.mean(0)) + b.mean(0) - b
        assert residual[n] == pytest.approx(np.sqrt((miss**2).sum(1).mean()), rel=1e-9)
        assert residual[n] > 1e-3  # every offset matters: millimetres, not round-off
    assert residual[2] == pytest.approx(0.0, abs=1e-12)


def test_a_known_pose_is_recovered_from_noiseless_markers():
    r = Rotation.from_rotvec([[0.3, -1.2, 2.0], [0.0, 0.0, 0.0]])
    p = np.array([[0.5, 1.0, -0.2], [0.0, 0.0, 0.0]])
    got_p, got_q, valid, _ = fit_pose(LAYOUT, place(LAYOUT, r, p))
    expected = r.as_quat(scalar_first=True)
    expected *= np.where(expected[:, :1] < 0, -1, 1)
    assert valid.all()
    assert got_p == pytest.approx(p, abs=1e-12)
    assert got_q == pytest.approx(expected, abs=1e-12) and (got_q[:, 0] >= 0).all()


def test_fewer_than_three_markers_seen_is_invalid():
    layout = LAYOUT[:3]
    observed = place(layout, Rotation.from_rotvec([[0.1, 0.2, 0.3]] * 2), np.zeros((2, 3)))
    observed[1, 0] = np.nan  # frame 1: 2 of 3 markers
    p, q, valid, _ = fit_pose(layout, observed)
    assert list(valid) == [True, False]
    assert np.isnan(p[1]).all() and np.isnan(q[1]).all()
    assert np.isfinite(p[0]).all() and np.isfinite(q[0]).all()


def test_the_reflection_fix_coplanar_markers_give_the_rotation_not_its_mirror():
    # three markers are always coplanar: the SVD's third axis has no preferred sign, and without
    # the fix some of these poses come back as the rotation of a mirror image
    layout = LAYOUT[:3]
    r = Rotation.random(64, random_state=3)
    p = np.random.default_rng(3).normal(size=(64, 3))
    got_p, got_q, valid, _ = fit_pose(layout, place(layout, r, p))
    expected = r.as_quat(scalar_first=True)
    expected *= np.where(expected[:, :1] < 0, -1, 1)
    assert valid.all()
    assert got_q == pytest.approx(expected, abs=1e-9)
    assert got_p == pytest.approx(p, abs=1e-9)
