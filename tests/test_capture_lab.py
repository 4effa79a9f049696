"""The lab file (embodied_snap/capture/lab.py, schemas/lab.schema.yaml): a valid one loads, each kind
of bad one is refused in one line, and its axes and bodies give lab-frame poses.

Expected values are written out by hand (the arithmetic is in the comments), never computed by the
code under test.
"""

from __future__ import annotations

import copy
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
import yaml

from embodied_snap.capture.errors import CaptureError
from embodied_snap.capture.lab import load_lab

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "lab.yaml"
LABFORMATS = Path(__file__).resolve().parents[2] / "shared" / "labformats"
RESIDUAL_M = yaml.safe_load((EXAMPLE.parents[2] / "config.yaml").read_text())["capture"]["max_marker_residual_mm"] / 1e3
NAN = float("nan")

LAB = {
    "capture": {"axes": "z_up"},
    "bodies": {
        "base": {"rigid_body": "Base"},
        "s1": {"rigid_body": "S1"},
        "s2": {"rigid_body": "S2"},
        "tip": {"markers": {"m1": [0.02, 0.0, 0.0], "m2": [0.0, 0.03, 0.0], "m3": [0.0, 0.0, 0.04]}},
    },
    "servos": [11, 12, 13, 21, 22, 23, 31, 32, 33],
    "arm": {"arm_length_m": 0.73, "tendon_radius_m": [0.037, 0.022, 0.022], "end_effector_m": 0.15},
    "clock": {"sync": {"column": "sync"}, "max_drift_ppm": 50},
}


def write(tmp_path, edit=None):
    doc = copy.deepcopy(LAB)
    if edit:
        edit(doc)
    path = tmp_path / "lab.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def refused(tmp_path, edit):
    path = write(tmp_path, edit)
    with pytest.raises(CaptureError) as e:
        load_lab(path)
    msg = str(e.value)
    assert "\n" not in msg
    # one line: the file, what was found, the rule it breaks; the tests compare what was found
    assert e.value.rule and msg == f"{path}: {e.value.what} (rule: {e.value.rule})"
    return e.value.what


def test_a_valid_lab_file_loads(tmp_path):
    lab = load_lab(write(tmp_path))
    assert lab.servos == (11, 12, 13, 21, 22, 23, 31, 32, 33)
    assert lab.bodies["base"] == {"rigid_body": "Base"}
    assert lab.clock == {"sync": {"column": "sync"}, "max_drift_ppm": 50, "max_offset_s": 0.15}  # the default
    assert lab.arm["end_effector_m"] == 0.15


def test_the_example_lab_file_loads():
    lab = load_lab(EXAMPLE)
    assert set(lab.bodies) == {"base", "s1", "s2", "tip", "target"}
    assert len(lab.servos) == 9


def test_a_missing_body(tmp_path):
    assert refused(tmp_path, lambda d: d["bodies"].pop("tip")) == "bodies: 'tip' is a required property"


@pytest.mark.parametrize(
    "edit, where",
    [
        (lambda d: d.update(colour="red"), ""),
        (lambda d: d["capture"].update(origin=[0, 0, 0]), "capture: "),
        (lambda d: d["bodies"].update(elbow={"rigid_body": "Elbow"}), "bodies: "),
        (lambda d: d["bodies"]["base"].update(colour="red"), "bodies.base: "),
    ],
)
def test_an_unknown_key(tmp_path, edit, where):
    key = refused(tmp_path, edit).removeprefix(where)
    assert key.startswith("Additional properties are not allowed (") and key.endswith(" was unexpected)")


def test_two_markers(tmp_path):
    msg = refused(tmp_path, lambda d: d["bodies"]["tip"]["markers"].pop("m3"))
    assert msg == "bodies.tip.markers: needs at least 3 markers (the pose about the line through 2 is undetermined)"


@pytest.mark.parametrize(
    "body, rule",
    [
        ({}, "bodies.tip: needs rigid_body, bone or at least 3 markers"),
        ("Tip", "bodies.tip: needs rigid_body, bone or at least 3 markers"),
        ({"rigid_body": "Tip", "markers": {"a": [0, 0, 0], "b": [1, 0, 0], "c": [0, 1, 0]}},
         "bodies.tip: one of rigid_body, bone or markers"),
        ({"markers": {"a": [0, 0], "b": [1, 0, 0], "c": [0, 1, 0]}},
         "bodies.tip.markers.a: a marker is [x, y, z] in the body frame, in metres"),
        ({"markers": {1: [0, 0, 0], "b": [1, 0, 0], "c": [0, 1, 0]}},
         "bodies.tip.markers: a marker label is a non-empty string: quote a label YAML reads as a number or boolean"),
    ],
)
def test_a_body_the_schema_refuses(tmp_path, body, rule):
    assert refused(tmp_path, lambda d: d["bodies"].update(tip=body)) == rule


@pytest.mark.parametrize(
    "edit, rule",
    [
        (lambda d: d["capture"].update(axes="x_up"),
         "capture.axes: y_up, z_up or a 3x3 rotation matrix (three rows of three numbers)"),
        (lambda d: d["capture"].update(axes=[[1, 0, 0], [0, 1, 0]]),
         "capture.axes: y_up, z_up or a 3x3 rotation matrix (three rows of three numbers)"),
        (lambda d: d["servos"].__setitem__(8, 253), "servos.8: 253 is greater than the maximum of 252"),
        (lambda d: d["servos"].pop(), "servos: [11, 12, 13, 21, 22, 23, 31, 32] is too short"),
        (lambda d: d["clock"].update(sync="ntp"),
         "clock.sync: none, {column: <name in the servo log>} or {event_time_s: <seconds>}"),
        (lambda d: d["clock"].pop("max_drift_ppm"), "clock: 'max_drift_ppm' is a required property"),
        (lambda d: d["arm"].pop("arm_length_m"), "arm: 'arm_length_m' is a required property"),
    ],
)
def test_other_schema_rules(tmp_path, edit, rule):
    assert refused(tmp_path, edit) == rule


def test_a_duplicate_servo_id(tmp_path):
    msg = refused(tmp_path, lambda d: d["servos"].__setitem__(3, 13))
    assert msg == "servos: id 13 is given twice (servo columns 3 and 4)"


def test_a_reflection_is_not_a_rotation(tmp_path):
    # orthonormal, determinant -1: a capture frame mirrored in Z
    msg = refused(tmp_path, lambda d: d["capture"].update(axes=[[1, 0, 0], [0, 1, 0], [0, 0, -1]]))
    assert msg == "capture.axes: determinant -1, a reflection (a left-handed frame?)"


def test_a_shear_is_not_a_rotation(tmp_path):
    # determinant +1 (triangular, ones on the diagonal) but rows not orthonormal
    msg = refused(tmp_path, lambda d: d["capture"].update(axes=[[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]))
    assert msg == "capture.axes: the rows are not orthonormal (within 1e-06)"


def test_a_rotation_matrix_loads(tmp_path):
    # the z_up convention written as its matrix
    lab = load_lab(write(tmp_path, lambda d: d["capture"].update(axes=[[1, 0, 0], [0, 0, 1], [0, -1, 0]])))
    assert lab.to_lab_frame([1.0, 2.0, 3.0]) == pytest.approx([1.0, 3.0, -2.0])


def test_three_collinear_markers(tmp_path):
    # m1, m2, m4 lie on the x axis; m3 makes the layout as a whole a plane, which does not help a
    # frame in which m3 is occluded
    markers = {"m1": [0.0, 0, 0], "m2": [0.05, 0, 0], "m3": [0.0, 0.04, 0], "m4": [0.1, 0, 0]}
    msg = refused(tmp_path, lambda d: d["bodies"]["tip"].update(markers=markers))
    assert msg == ("bodies.tip.markers: m1, m2, m4 lie on one line (within 1 mm): "
                   "a frame that sees only them has no rotation about it")


def test_a_number_that_is_not_finite(tmp_path):
    msg = refused(tmp_path, lambda d: d["arm"].update(arm_length_m=NAN))
    assert msg == "arm.arm_length_m: nan"


def test_not_yaml(tmp_path):
    path = tmp_path / "lab.yaml"
    path.write_text("capture: [y_up\n")
    with pytest.raises(CaptureError, match=r"^.*lab\.yaml: not readable as YAML \(.*\)$"):
        load_lab(path)


def test_to_lab_frame_z_up(tmp_path):
    lab = load_lab(write(tmp_path))
    # z_up: lab = (x, z, -y); the capture's up (0, 0, 1) is the lab's (0, 1, 0)
    lab_points = lab.to_lab_frame([[1.0, 2.0, 3.0], [0.0, 0.0, 1.0]])
    assert lab_points == pytest.approx(np.array([[1.0, 3.0, -2.0], [0.0, 1.0, 0.0]]))


def same_rotation(q, expected):
    q, expected = np.asarray(q, float), np.asarray(expected, float)
    return q * np.sign(q @ expected) == pytest.approx(expected, abs=1e-9)  # q and -q are one rotation


def markers(rows):
    xyz = np.array(rows, float)
    return pd.DataFrame({"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "valid": ~np.isnan(xyz).any(1)})


def test_body_pose_from_markers(tmp_path):
    lab = load_lab(write(tmp_path))
    # The tip turned 90 deg about the lab's Y, (x, y, z) -> (z, y, -x), at p = (0.1, 0.2, 0.3):
    # m1 (0.02, 0, 0) -> (0.1, 0.2, 0.28), m2 (0, 0.03, 0) -> (0.1, 0.23, 0.3),
    # m3 (0, 0, 0.04) -> (0.14, 0.2, 0.3); as a Z-up capture writes them, (x, -z, y) of those.
    # Frame 1 has m3 occluded: two markers, no pose.
    take = SimpleNamespace(path=Path("take.c3d"), t=np.array([0.0, 0.01]), markers={
        "m1": markers([[0.1, -0.28, 0.2], [0.1, -0.28, 0.2]]),
        "m2": markers([[0.1, -0.3, 0.23], [0.1, -0.3, 0.23]]),
        "m3": markers([[0.14, -0.3, 0.2], [NAN, NAN, NAN]]),
        "other": markers([[9.0, 9.0, 9.0], [9.0, 9.0, 9.0]]),
    })
    p, q, valid = lab.body_pose(take, "tip", RESIDUAL_M)
    assert valid.tolist() == [True, False]
    assert p[0] == pytest.approx([0.1, 0.2, 0.3], abs=1e-9)
    assert same_rotation(q[0], [0.7071067811865476, 0.0, 0.7071067811865476, 0.0])  # cos 45, 0, sin 45, 0
    assert np.isnan(p[1]).all() and np.isnan(q[1]).all()


def test_body_pose_from_a_rigid_body(tmp_path):
    lab = load_lab(write(tmp_path))
    # frame 0: identity in the capture, so the lab quaternion is the axes' turn, -90 deg about X:
    #   (cos -45, sin -45, 0, 0); frame 1: 90 deg about the capture's Z (its up), which is
    #   90 deg about the lab's Y after the axes' turn: (c, 0, s, 0) x (c, -s, 0, 0), c = s = 1/sqrt 2,
    #   = (0.5, -0.5, 0.5, 0.5); frame 2: occluded (Motive leaves the cells blank)
    c = 0.7071067811865476
    body = pd.DataFrame({
        "x": [1.0, 0.1, NAN], "y": [2.0, 0.2, NAN], "z": [3.0, 0.3, NAN],
        "qw": [1.0, c, NAN], "qx": [0.0, 0.0, NAN], "qy": [0.0, 0.0, NAN], "qz": [0.0, c, NAN],
        "valid": [True, True, False],
    })
    take = SimpleNamespace(path=Path("take.csv"), rigid_bodies={"S1": body}, markers={})
    p, q, valid = lab.body_pose(take, "s1", RESIDUAL_M)
    assert valid.tolist() == [True, True, False]
    assert p[:2] == pytest.approx(np.array([[1.0, 3.0, -2.0], [0.1, 0.3, -0.2]]))
    assert same_rotation(q[0], [c, -c, 0.0, 0.0])
    assert same_rotation(q[1], [0.5, -0.5, 0.5, 0.5])
    assert np.isnan(p[2]).all() and np.isnan(q[2]).all()


def test_body_pose_names_what_the_take_lacks(tmp_path):
    lab = load_lab(write(tmp_path))
    take = SimpleNamespace(path=Path("take.csv"), rigid_bodies={}, markers={"m1": markers([[0.0, 0, 0]])})
    with pytest.raises(CaptureError, match=r"^take\.csv: no rigid body 'S1' \(the lab file's s1\) \(rule: [^()]+\)$"):
        lab.body_pose(take, "s1", RESIDUAL_M)
    with pytest.raises(CaptureError, match=r"^take\.csv: no marker 'm2' \(the lab file's tip\) \(rule: [^()]+\)$"):
        lab.body_pose(take, "tip", RESIDUAL_M)
    with pytest.raises(CaptureError, match=r"lab\.yaml: bodies: no 'target' \(it names base, s1, s2, tip\) \(rule: "):
        lab.body_pose(take, "target", RESIDUAL_M)


# --- two arm bodies on one capture body ---------------------------------------------------------


@pytest.mark.parametrize(
    "edit, what",
    [
        (lambda d: d["bodies"].update(s2={"rigid_body": "S1"}), "bodies.s1 and bodies.s2 both map to rigid body 'S1'"),
        (lambda d: d["bodies"].update(base={"bone": "Arm"}, s2={"bone": "Arm"}),
         "bodies.base and bodies.s2 both map to bone 'Arm'"),
        (lambda d: d["bodies"].update(target={"markers": {"m1": [0.0, 0.0, 0.0], "t2": [0.02, 0.0, 0.0],
                                                          "t3": [0.0, 0.02, 0.0]}}),
         "bodies.tip and bodies.target both map to marker 'm1'"),
    ],
    ids=["rigid-body", "bone", "marker"],
)
def test_two_arm_bodies_on_one_capture_body(tmp_path, edit, what):
    # the arm would read as zero length between them: the lab file is refused, naming both
    assert refused(tmp_path, edit) == what


def test_a_rigid_body_and_a_bone_of_one_name_are_two_bodies(tmp_path):
    lab = load_lab(write(tmp_path, lambda d: d["bodies"].update(s2={"bone": "S1"})))
    assert lab.bodies["s2"] == {"bone": "S1"}


# --- real exports (read from ../shared/labformats; skipped where absent) ---------------------------


@pytest.fixture
def real():
    if not LABFORMATS.is_dir():
        pytest.skip("the real capture exports are not on this machine")
    return LABFORMATS


def as_bones(real, tmp_path):
    """motive123_m_single_rigidbody_240hz.csv with its Rigid Body written as a skeleton's Bone."""
    path = tmp_path / "bones.csv"
    text = (real / "motive123_m_single_rigidbody_240hz.csv").read_bytes().decode()
    path.write_bytes(text.replace(",Type,Rigid Body,", ",Type,Bone,").replace(",Rigid Body", ",Bone").encode())
    return path


def y_up(**bodies):
    return lambda d: (d["capture"].update(axes="y_up"), d["bodies"].update(bodies))


def test_a_bone_maps_like_a_rigid_body(real, tmp_path):
    from embodied_snap.capture.motive import read_motive_csv

    take = read_motive_csv(as_bones(real, tmp_path))
    assert take.rigid_bodies == {} and list(take.bones) == ["RigidBody"]
    lab = load_lab(write(tmp_path, y_up(s1={"bone": "RigidBody"})))
    p, q, valid = lab.body_pose(take, "s1", RESIDUAL_M)
    # line 8 of the export: X, Y, Z, W then the position, in metres; y_up keeps them as they are
    assert p[0] == pytest.approx([0.047597, 0.607298, 0.329784])
    assert same_rotation(q[0], [-0.163966, 0.715879, 0.252092, -0.630144])
    assert valid.all() and len(valid) == 10460


def test_a_bone_named_as_a_rigid_body_is_answered_as_a_bone(real, tmp_path):
    from embodied_snap.capture.motive import read_motive_csv

    take = read_motive_csv(as_bones(real, tmp_path))
    lab = load_lab(write(tmp_path, y_up(s1={"rigid_body": "RigidBody"})))
    with pytest.raises(CaptureError) as e:
        lab.body_pose(take, "s1", RESIDUAL_M)
    assert e.value.what == ("no rigid body 'RigidBody' (the lab file's s1): the take holds it as a Bone "
                            "(map it with bone: RigidBody)")


MARKERS = [f"ernesto_body:Marker{i}" for i in range(1, 5)]


def cluster(real, order=(0, 1, 2, 3)):
    """The 120 Hz export's four measured markers as a layout: Motive's own rigid-body markers (its
    solver's ideal positions) at frame 0, about their centre; `order` relabels them."""
    from embodied_snap.capture.motive import read_motive_csv

    take = read_motive_csv(real / "motive123_m_rigidbody_mme_markerquality_120hz.csv")
    ideal = np.array([take.body_markers[m].loc[0, ["x", "y", "z"]].to_numpy(float) for m in MARKERS])
    layout = ideal - ideal.mean(0)
    return take, {MARKERS[i]: [float(v) for v in layout[j]] for i, j in zip(range(4), order)}


def test_a_marker_cluster_within_the_residual_limit_fits(real, tmp_path):
    take, layout = cluster(real)
    lab = load_lab(write(tmp_path, y_up(tip={"markers": layout})))
    p, q, valid = lab.body_pose(take, "tip", RESIDUAL_M)
    # every frame sees the four markers (frame 4 blanks the solved body, not them); the fit moves as
    # Motive's own rigid body does: their centres keep one offset to within the markers' ~1 mm
    assert valid.all()
    body = take.rigid_bodies["ernesto_body"]
    ok = body.valid.to_numpy()
    offset = p[ok] - body.loc[ok, ["x", "y", "z"]].to_numpy(float)
    assert np.abs(offset - offset[0]).max() < 2e-3


def test_a_marker_cluster_past_the_residual_limit_is_refused(real, tmp_path):
    # Marker1 and Marker2 labelled the wrong way round in the lab file: no pose fits both
    take, layout = cluster(real, order=(1, 0, 2, 3))
    lab = load_lab(write(tmp_path, y_up(tip={"markers": layout})))
    with pytest.raises(CaptureError) as e:
        lab.body_pose(take, "tip", RESIDUAL_M)
    assert str(e.value).startswith(f"{take.path}: the lab file's tip markers fit its layout to ")
    assert e.value.rule == f"marker fit residual <= {RESIDUAL_M * 1e3:g} mm (config capture.max_marker_residual_mm)"
    assert "\n" not in str(e.value)
    # the same layout with a limit above its worst frame passes (the limit is what decides)
    assert lab.body_pose(take, "tip", 0.1)[2].all()
