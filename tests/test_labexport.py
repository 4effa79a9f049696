"""tests/labexport.py, the lab-export writers, checked by a round trip through the capture readers
(embodied_snap.capture): what a fakerig group is written as must read back as that group.

Figures measured on fakerig's dyn_0001 (6 s, seed 0), asserted with the margins below:
- Motive CSV, 120 Hz: positions equal the native even samples to 5e-7 of the file's unit (6
  decimals: 5e-10 m in mm, 5e-7 m in Meters), quaternions to 5e-7 per component, up to sign.
- Motive CSV, 360 Hz: a frame lies at f = 1/3 or 2/3 of a native interval h = 1/240 s, where
  linear interpolation errs by f (1 - f) h^2 / 2 |a| = h^2 / 9 |a| (a the acceleration, from the
  native second differences): 3.1e-5 m for the tip (max |a| 16 m/s^2 at the snap), 1.3e-5 m for s2,
  5.2e-6 m for s1, 0 for the static base and target. The errors measured against fakerig's
  closed-form poses reach these bounds (3.07e-5, 1.31e-5, 5.23e-6 m): the test allows 10 % over.
  Slerp of a rotation about a fixed axis (fakerig's bends) errs by h^2 / 9 times the angular
  acceleration in the same way: 5.5e-5 rad for the tip, reached likewise.
- C3D, 4 markers per body centred on its origin, 0.5 mm noise per axis, z-up axes, 2 extra gaps
  per marker: on the frames that see all 4 the fitted position errs by 0.94-1.05 sigma / sqrt(4)
  (0.25 mm) per axis RMS, 1.71-1.76 sigma / sqrt(k) (about 0.43 mm) RMS in 3D, at most 1.1 mm;
  the test holds the 3D RMS under 3 sigma / sqrt(k) and each axis within 20 % of sigma / sqrt(k).
  Orientations: 0.86 deg RMS. 35-58 frames per body see 3 markers and still fit.
- Servo log at 0.137 s offset, 20 ppm drift: estimate_offset on the present-position speed of the
  native log against the written one gives 0.13673 s, 0.27 ms short, which is the drift's share
  (20 ppm of the servo clock's ~15 s reading, 0.31 ms): one native capture frame is 4.2 ms.

fakerig's bodies do not follow its servos: the arm's angles are a closed-form sway plus a snap at
3.0 s, and the servos step at 0.5, 2.9 and 4.5 s, so over the whole take the tip speed and the servo
speed correlate at most 0.22 (estimate_offset refuses: flat correlation). Only in a window around the
snap do they share a motion, 0.099 s apart (fakerig's release-to-snap delay, r = 0.71): the test
fits that delay on an unshifted log and checks that the shifted log moves it by the offset (measured
0.1367 s, 0.34 ms short: the drift again).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.spatial.transform import Rotation

from embodied_snap.capture.c3d import read_c3d
from embodied_snap.capture.clock import ClockFitOptions, estimate_offset
from embodied_snap.capture.errors import CaptureError
from embodied_snap.capture.lab import load_lab
from embodied_snap.capture.motive import read_motive_csv
from embodied_snap.rawformat import BODIES, MOCAP_HZ, servo_columns

from fakerig import make_mocap, write_fake_group
from labexport import (
    DEFAULT_NAMES,
    resample_poses,
    servo_clock,
    write_c3d,
    write_motive_csv,
    write_operator_labels,
    write_servo_log,
)

LABFORMATS = Path(__file__).resolve().parents[2] / "shared" / "labformats"
REAL_123 = "motive123_m_single_rigidbody_240hz.csv"
H = 1 / MOCAP_HZ
OFFSET_S, DRIFT_PPM = 0.137, 20.0


@pytest.fixture(scope="module")
def group(tmp_path_factory):
    raw = tmp_path_factory.mktemp("raw")
    write_fake_group(raw)
    g = raw / "groups" / "dyn_0001"
    return {
        "mocap": pd.read_parquet(g / "mocap.parquet"),
        "servo": pd.read_parquet(g / "servo.parquet"),
        "meta": json.loads((g / "meta.json").read_text()),
    }


def native(mocap, body):
    p = mocap[[f"{body}_{a}" for a in "xyz"]].to_numpy(float)
    q = mocap[[f"{body}_{c}" for c in ("qw", "qx", "qy", "qz")]].to_numpy(float)
    return p, q, mocap[f"{body}_valid"].to_numpy(bool)


def xyz(table):
    return table[["x", "y", "z"]].to_numpy(float)


def wxyz(table):
    return table[["qw", "qx", "qy", "qz"]].to_numpy(float)


def up_to_sign(a, b):
    """Per frame, the larger component difference of a and b or of a and -b, whichever is smaller."""
    return np.minimum(np.abs(a - b).max(1), np.abs(a + b).max(1))


# --- Motive CSV -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("units, rounding_m", [("Millimeters", 5e-10), ("Centimeters", 5e-9), ("Meters", 5e-7)])
def test_motive_120_hz_reads_back_as_the_even_native_samples(group, tmp_path, units, rounding_m):
    mocap = group["mocap"]
    path = tmp_path / "take.csv"
    out = write_motive_csv(mocap, path, rate_hz=120, units=units, occlusions=3, rng=np.random.default_rng(1),
                           sign_flips=0.2, mean_marker_error=True)
    take = read_motive_csv(path)
    assert (take.version, take.rate_hz, take.units, take.rotation) == ("1.23", 120.0, units, "Quaternion")
    n = (len(mocap) + 1) // 2
    assert take.total_frames == len(take.t) == n
    np.testing.assert_array_equal(take.frame, np.arange(n))
    np.testing.assert_allclose(take.t, np.arange(n) / 120, atol=5e-7)
    np.testing.assert_allclose(out.t, mocap.t.to_numpy()[::2])
    assert sorted(take.rigid_bodies) == sorted(DEFAULT_NAMES.values())
    flipped = 0
    for body, name in DEFAULT_NAMES.items():
        table = take.rigid_bodies[name]
        p, q, v = (a[::2] for a in native(mocap, body))
        valid = table["valid"].to_numpy()
        # the occluded frames: the native dropouts at even samples, and the extra gaps, exactly
        np.testing.assert_array_equal(valid, out.poses[body][2])
        assert not valid[~v].any() and (~valid & v).any()
        assert np.isnan(xyz(table)[~valid]).all()
        # the writer's rounding: 6 decimals of the unit; 1e-6 m holds for any unit
        err = np.abs(xyz(table)[valid] - p[valid]).max()
        assert err <= rounding_m * 1.01 + 1e-12 and err < 1e-6
        assert up_to_sign(wxyz(table)[valid], q[valid]).max() <= 5.1e-7
        flipped += (np.abs(wxyz(table)[valid] + q[valid]).max(1) < 1e-6).sum()
    assert flipped > 0  # some quaternions were written as -q, and read back as equal up to sign


def test_motive_360_hz_positions_within_the_interpolation_bound(group, tmp_path):
    mocap = group["mocap"]
    path = tmp_path / "take360.csv"
    out = write_motive_csv(mocap, path, rate_hz=360, units="Millimeters")
    take = read_motive_csv(path)
    assert take.rate_hz == 360.0
    t = mocap.t.to_numpy()
    t360 = t[0] + np.arange(len(take.t)) / 360
    assert t360[-1] <= t[-1] + 1e-9 and t360[-1] + 1 / 360 > t[-1]
    np.testing.assert_allclose(out.t, t360)
    truth = make_mocap(t360, dropouts=())  # fakerig's closed form at the 360 Hz times
    worst = []
    for body, name in DEFAULT_NAMES.items():
        table = take.rigid_bodies[name]
        p, q, v = native(mocap, body)
        valid = table["valid"].to_numpy()
        # a 360 Hz frame is valid exactly where both native samples around it are
        i = np.clip(np.searchsorted(t, t360 - 1e-9) - 1, 0, len(t) - 2)
        on = np.isclose(t360, t[i + 1])
        expect = np.where(on, v[np.minimum(i + 1, len(t) - 1)], v[i] & v[i + 1])
        np.testing.assert_array_equal(valid, expect)
        # positions: a 360 Hz frame lies at f = 1/3 or 2/3 of a native interval h, where linear
        # interpolation errs by f (1 - f) h^2 / 2 |a| = h^2 / 9 |a| (a: the acceleration, from the
        # native second differences; 10 % for their averaging over 2 h), + the 6-decimal rounding
        fine = v[2:] & v[1:-1] & v[:-2]
        acc = np.linalg.norm(p[2:] - 2 * p[1:-1] + p[:-2], axis=1)[fine] / H**2
        bound = H**2 / 9 * acc.max() * 1.1 + 1e-9
        tp, tq, _ = native(truth, body)
        err = np.linalg.norm(xyz(table)[valid] - tp[valid], axis=1).max()
        assert err <= bound, (body, err, bound)
        # orientations: fakerig's bodies turn about a fixed axis, where slerp interpolates the angle
        # linearly: the same bound with the angular acceleration, + the quaternions' rounding (2e-6 rad)
        r = Rotation.from_quat(np.where(v[:, None], q, [1.0, 0, 0, 0]), scalar_first=True)
        w = (r[:-1].inv() * r[1:]).as_rotvec() / H  # body-frame angular velocity over each interval
        alpha = np.linalg.norm(w[1:] - w[:-1], axis=1)[fine] / H
        ang_bound = H**2 / 9 * alpha.max() * 1.1 + 2e-6
        got = Rotation.from_quat(wxyz(table)[valid], scalar_first=True)
        ang = (got.inv() * Rotation.from_quat(tq[valid], scalar_first=True)).magnitude().max()
        assert ang <= ang_bound, (body, ang, ang_bound)
        worst.append(err / bound)
    assert max(worst) > 0.8  # measured 0.91 (tip, s1, s2): the bound is reached, not loose


def test_motive_header_is_laid_out_as_motive_123_writes_it(group, tmp_path):
    if not (LABFORMATS / REAL_123).is_file():
        pytest.skip("the real capture exports are not on this machine")
    path = tmp_path / "take.csv"
    write_motive_csv(group["mocap"], path, rate_hz=120, names={"tip": "Tip"})
    mine = path.read_bytes().split(b"\r\n")
    with open(LABFORMATS / REAL_123, "rb") as f:
        real = [f.readline() for _ in range(9)]
    assert all(line.endswith(b"\r\n") for line in real) and path.read_bytes().endswith(b"\r\n")
    real = [line[:-2] for line in real]
    # the metadata row: the same keys in the same order
    assert mine[0].split(b",")[0::2] == real[0].split(b",")[0::2]
    assert mine[1] == real[1] == b""
    # Type, Name, ID, component and axis rows: one rigid body, the same cells but its name and GUID
    assert mine[2] == real[2].replace(b"RigidBody", b"Tip")
    assert mine[3] == real[3].replace(b"RigidBody", b"Tip")
    guid = mine[4].split(b",")[2]
    assert len(guid) == 34 and guid[:1] == guid[-1:] == b'"' and guid[1:-1].isalnum() and guid.upper() == guid
    assert mine[4] == real[4].replace(real[4].split(b",")[2], guid)
    assert mine[5:7] == real[5:7]
    # data rows: unquoted, 6 decimals
    assert mine[7].split(b",")[:2] == [b"0", b"0.000000"]
    assert all(len(c.split(b".")[1]) == 6 for c in mine[7].split(b",")[1:])


def test_motive_writer_refuses_what_it_does_not_lay_out(group, tmp_path):
    with pytest.raises(ValueError, match="1.25"):
        write_motive_csv(group["mocap"], tmp_path / "a.csv", version="1.25")
    with pytest.raises(ValueError, match="units"):
        write_motive_csv(group["mocap"], tmp_path / "a.csv", units="Inches")


# --- C3D ------------------------------------------------------------------------------------------------


def layouts():
    """4 markers per body, a tetrahedron a few cm across, turned differently per body, centred on
    the body's origin (so the fitted position is the markers' mean)."""
    tet = np.array([[0.04, 0.0, -0.01], [-0.02, 0.035, 0.0], [-0.02, -0.035, 0.01], [0.0, 0.0, 0.03]])
    tet -= tet.mean(0)
    return {b: Rotation.from_euler("y", 40 * k, degrees=True).apply(tet) for k, b in enumerate(BODIES)}


def write_lab(tmp_path, lays, axes):
    doc = {
        "capture": {"axes": axes},
        "bodies": {b: {"markers": {f"{DEFAULT_NAMES[b]}:M{j + 1}": [float(c) for c in m] for j, m in enumerate(lay)}}
                   for b, lay in lays.items()},
        "servos": list(range(1, 10)),
        "arm": {"arm_length_m": 0.73, "tendon_radius_m": [0.037, 0.022, 0.022], "end_effector_m": 0.15},
        "clock": {"sync": "none", "max_drift_ppm": 100},
    }
    path = tmp_path / "lab.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return load_lab(path)


def test_c3d_markers_fit_back_to_the_poses(group, tmp_path):
    mocap, noise, lays = group["mocap"], 0.0005, layouts()
    path = tmp_path / "take.c3d"
    out = write_c3d(mocap, path, lays, rate_hz=120, noise_m=noise, rng=np.random.default_rng(2), axes="z_up",
                    occlusions=2)
    take = read_c3d(path)
    assert (take.rate_hz, take.units, take.first_frame) == (120.0, "mm", 1)
    n = len(out.t)
    np.testing.assert_allclose(take.t, np.arange(n) / 120)
    assert set(take.markers) == {f"{DEFAULT_NAMES[b]}:M{j}" for b in BODIES for j in range(1, 5)}
    lab = write_lab(tmp_path, lays, "z_up")
    for label, table in take.markers.items():  # the points, back in the lab frame: float32 storage of mm
        seen = table["valid"].to_numpy()
        np.testing.assert_array_equal(seen, np.isfinite(out.markers[label]).all(1))
        np.testing.assert_allclose(lab.to_lab_frame(xyz(table))[seen], out.markers[label][seen], atol=2e-7)
    k, bound = 4, noise / np.sqrt(4)
    for body in BODIES:
        p, q, valid = lab.body_pose(take, body, 10 * noise)  # RMS over the markers: ~ the noise
        tp, tq, tv = (a[::2] for a in native(mocap, body))
        seen = np.stack([take.markers[f"{DEFAULT_NAMES[body]}:M{j}"]["valid"] for j in range(1, 5)], 1)
        np.testing.assert_array_equal(valid, tv & (seen.sum(1) >= 3))
        full = valid & (seen.sum(1) == k)  # all markers seen: the position error is the noise's mean
        e = p[full] - tp[full]
        rms3, rms_axis = np.sqrt((e**2).sum(1).mean()), np.sqrt((e**2).mean(0))
        assert rms3 < 3 * bound, (body, rms3)
        assert np.all(np.abs(rms_axis / bound - 1) < 0.2), (body, rms_axis)
        # with 3 of 4 seen the pose still comes back, a little worse
        three = valid & (seen.sum(1) == 3)
        assert three.sum() > 0 and np.linalg.norm(p[three] - tp[three], axis=1).max() < 10 * noise
        ang = (Rotation.from_quat(q[valid], scalar_first=True).inv()
               * Rotation.from_quat(tq[valid], scalar_first=True)).magnitude()
        assert np.sqrt((ang**2).mean()) < 3 * noise / 0.03  # noise over the cluster's size, in rad


def test_resampling_a_rate_that_divides_240_takes_native_samples(group):
    mocap = group["mocap"]
    t, poses = resample_poses(mocap, ["tip"], 80)
    np.testing.assert_array_equal(t, mocap.t.to_numpy()[::3])
    np.testing.assert_array_equal(poses["tip"][0], native(mocap, "tip")[0][::3])


# --- servo log and clocks ------------------------------------------------------------------------------


def speed(t, ticks):
    """Summed |d ticks / dt| of the nine servos at the midpoints of the samples."""
    return 0.5 * (t[1:] + t[:-1]), np.abs(np.diff(ticks, axis=0)).sum(1) / np.diff(t)


def present(servo):
    return servo[[f"present_{i}" for i in range(1, 10)]].to_numpy(float)


def test_servo_log_is_on_the_other_clock(group, tmp_path):
    servo = group["servo"]
    path = tmp_path / "servo.csv"
    t_written = write_servo_log(servo, path, OFFSET_S, DRIFT_PPM)
    log = pd.read_csv(path)
    assert list(log.columns) == servo_columns()
    for c in servo_columns()[1:]:
        if not c.startswith("current_"):
            assert log[c].dtype == np.int64
            np.testing.assert_array_equal(log[c].to_numpy(), servo[c].to_numpy())
    t = servo.t.to_numpy()
    np.testing.assert_allclose(log.t.to_numpy(), (t - OFFSET_S) * (1 + DRIFT_PPM * 1e-6), atol=5e-7)
    np.testing.assert_allclose(t_written, servo_clock(t, OFFSET_S, DRIFT_PPM))
    # the inverse, which an importer must find: t = t' / (1 + drift) + offset_s
    np.testing.assert_allclose(log.t.to_numpy() / (1 + DRIFT_PPM * 1e-6) + OFFSET_S, t, atol=1e-6)

    # the offset from the same motion on both clocks: the servos' measured speed, native vs written
    fit = estimate_offset(*speed(t, present(servo)), *speed(log.t.to_numpy(), present(log)),
                          ClockFitOptions(max_shift_s=0.5))
    assert abs(fit.offset_s - OFFSET_S) < H  # one native capture frame
    # what is left is the drift: at the log's mid-time the constant shift is offset_s - t' drift
    t_mid = log.t.to_numpy().mean()
    assert abs(fit.offset_s - (OFFSET_S - t_mid * DRIFT_PPM * 1e-6)) < 2e-4


def test_tip_snap_and_servo_release_move_by_the_offset(group, tmp_path):
    """fakerig's only shared motion: the snap (mocap) and the release (servos), in a window."""
    mocap, servo = group["mocap"], group["servo"]
    write_motive_csv(mocap, tmp_path / "take.csv", rate_hz=120)
    take = read_motive_csv(tmp_path / "take.csv")
    tip = take.rigid_bodies["Tip"]
    t_mocap = mocap.t.iloc[0] + take.t  # the export counts from its first frame
    ok = tip["valid"].to_numpy()
    tm, sp = speed(t_mocap[ok], xyz(tip)[ok])
    window = (tm > mocap.t.iloc[0] + 2.2) & (tm < mocap.t.iloc[0] + 4.0)
    fits = []
    for offset, drift in ((0.0, 0.0), (OFFSET_S, DRIFT_PPM)):
        write_servo_log(servo, tmp_path / "servo.csv", offset, drift)
        log = pd.read_csv(tmp_path / "servo.csv")
        fits.append(estimate_offset(tm[window], sp[window], *speed(log.t.to_numpy(), present(log)),
                                    ClockFitOptions(max_shift_s=0.4, min_overlap_s=1.5)))
    lag = fits[0].offset_s  # fakerig's release-to-snap delay, physics rather than clocks
    assert 0.05 < lag < 0.15 and fits[0].peak_correlation > 0.5
    assert abs(fits[1].offset_s - lag - OFFSET_S) < 1 / 120  # one frame of this export


def test_the_whole_take_shares_no_motion(group):
    """Over the whole take fakerig's tip speed and servo speed do not correlate (module docstring)."""
    mocap, servo = group["mocap"], group["servo"]
    p, _, v = native(mocap, "tip")
    tm, sp = speed(mocap.t.to_numpy()[v], p[v])
    with pytest.raises(CaptureError, match="flat correlation"):
        estimate_offset(tm, sp, *speed(servo.t.to_numpy(), present(servo)), ClockFitOptions(max_shift_s=0.5))


# --- the operator's sheet -------------------------------------------------------------------------------


def test_operator_labels_one_sheet_per_session(group, tmp_path):
    meta = group["meta"]
    held = dict(meta, group_id="hb_0001", evidence_set="held_base", category="held",
                labels={"base_event_t": 14.25, "snap_speed_event": False, "t_preload": 13.0})
    att = dict(meta, group_id="att_0001", labels=dict(meta["labels"], attached=True, retrieved=False))
    meta_path = tmp_path / "meta.json"
    meta_path.write_text(json.dumps(meta))
    path = tmp_path / "s01_labels.csv"
    write_operator_labels([meta_path, held, att], path)
    assert path.read_text().splitlines() == [
        "group_id,attached,retrieved,base_event_t",
        "dyn_0001,false,false,",
        "hb_0001,,,14.25",
        "att_0001,true,false,",
    ]
    write_operator_labels([meta], path)
    assert path.read_text().splitlines() == ["group_id,attached,retrieved", "dyn_0001,false,false"]
    with pytest.raises(ValueError, match="one sheet per session"):
        write_operator_labels([meta, dict(meta, group_id="dyn_0002", session="s02")], path)
