"""A test helper, not an importer: a native group written out as a lab would have exported it.

The capture PC's export (a Motive CSV of rigid bodies, or a C3D of markers), the servo PC's log on
its own clock, and the operator's label sheet, from a group in the recording format
(docs/data.md; `tests/fakerig.py` writes such groups). An importer's test writes a native group
with these, imports the exports, and compares with the group it started from.

Clocks. The capture exports count time from their first frame (Motive's Time column, C3D's frame
index / rate): frame k of an export at rate_hz is the native mocap time t[0] + k / rate_hz. The
servo log is on another PC's clock (`write_servo_log`). Label times stay on the native mocap clock,
as the operator reads them off the capture software.

Resampling (both capture writers): a rate that divides 240 Hz takes every (240 / rate)-th native
sample, exactly; any other rate interpolates onto t[0] + k / rate: positions linearly, orientations
by slerp (scipy's Slerp), a frame being valid only where both native samples around it are.
"""

from __future__ import annotations

import csv
import uuid
from dataclasses import dataclass
from pathlib import Path

import ezc3d
import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation, Slerp

from embodied_snap.capture.lab import AXES
from embodied_snap.rawformat import BODIES, MOCAP_HZ, read_meta, servo_columns

DEFAULT_NAMES = {"base": "Base", "s1": "S1", "s2": "S2", "tip": "Tip", "target": "Target"}
FROM_METRES = {"Millimeters": 1e3, "Centimeters": 1e2, "Meters": 1.0}
# The versions whose header this writer reproduces: 1.25 adds a Parent row, not modelled here.
MOTIVE_VERSIONS = ("1.21", "1.22", "1.23", "1.24")
DECIMALS = 6  # Motive writes every number with 6 decimals, in the file's units
OPERATOR_LABELS = ("attached", "retrieved")
PUSH_LABEL = "base_event_t"  # held_base: when the operator's hand pushes on the mount


@dataclass(frozen=True, eq=False)
class Exported:
    """What a writer put in the file, before rounding, in the native lab frame and units."""

    t: np.ndarray  # native mocap-clock time of each exported frame: t[0] + k / rate_hz
    rate_hz: float
    poses: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]  # body -> p (n, 3) m, q (n, 4) wxyz, valid
    markers: dict[str, np.ndarray] | None = None  # C3D label -> (n, 3) lab frame, m, noise added, NaN occluded


# --- resampling -----------------------------------------------------------------------------------------


def resample_poses(mocap: pd.DataFrame, bodies, rate_hz: float):
    """(t, {body: (p, q, valid)}) at rate_hz from the native 240 Hz poses (see the module's docstring).

    Invalid frames have NaN p and q."""
    t = mocap["t"].to_numpy(float)
    step = MOCAP_HZ / rate_hz
    out = {}
    if step >= 1 and abs(step - round(step)) < 1e-9:
        idx = np.arange(0, len(t), int(round(step)))
        for b in bodies:
            p, q, v = _native(mocap, b)
            out[b] = (p[idx], q[idx], v[idx])
        return t[idx], out
    tk = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * rate_hz + 1e-6)) + 1) / rate_hz
    i = np.clip(np.searchsorted(t, tk, side="right") - 1, 0, len(t) - 1)
    exact = np.abs(tk - t[i]) < 1e-9
    j = np.where(exact, i, np.minimum(i + 1, len(t) - 1))
    for b in bodies:
        p, q, v = _native(mocap, b)
        ok = v[i] & v[j]
        pk = np.full((len(tk), 3), np.nan)
        qk = np.full((len(tk), 4), np.nan)
        if v.sum() >= 2 and ok.any():
            # between two valid native samples, the valid-only keys are those two: np.interp and Slerp
            # over them interpolate within that one interval
            for a in range(3):
                pk[ok, a] = np.interp(tk[ok], t[v], p[v, a])
            slerp = Slerp(t[v], Rotation.from_quat(q[v], scalar_first=True))
            qk[ok] = slerp(tk[ok]).as_quat(scalar_first=True)
        out[b] = (pk, qk, ok)
    return tk, out


def _native(mocap, body):
    p = mocap[[f"{body}_{a}" for a in "xyz"]].to_numpy(float)
    q = mocap[[f"{body}_{c}" for c in ("qw", "qx", "qy", "qz")]].to_numpy(float)
    v = mocap[f"{body}_valid"].to_numpy(bool) & np.isfinite(p).all(1) & np.isfinite(q).all(1)
    return p, q, v


def _gaps(n, occlusions, gap_frames, rng):
    """A mask (n,) True on `occlusions` random runs of gap_frames[0]..gap_frames[1] frames."""
    lost = np.zeros(n, bool)
    for _ in range(occlusions):
        k = int(rng.integers(gap_frames[0], gap_frames[1] + 1))
        start = int(rng.integers(0, max(n - k, 1)))
        lost[start : start + k] = True
    return lost


# --- Motive CSV -------------------------------------------------------------------------------------------


def write_motive_csv(
    mocap_df: pd.DataFrame,
    path,
    rate_hz: float = 120,
    units: str = "Millimeters",
    version: str = "1.23",
    occlusions: int = 0,
    rng=None,
    *,
    names: dict[str, str] | None = None,
    gap_frames: tuple[int, int] = (1, 10),
    sign_flips: float = 0.05,
    mean_marker_error: bool = False,
    take_name: str = "Take 2026-03-01 10.00.00 AM",
    start_time: str = "2026-03-01 10.00.00.000 AM",
    newline: str = "\r\n",
) -> Exported:
    """The group's bodies as Motive's rigid bodies, in a CSV laid out as Motive 1.23 writes one.

    Rows: the metadata row (key, value pairs), a blank row, the Type, Name and ID rows (their first
    cell blank, the tag in the second), the component row (Rotation x4, Position x3, and Mean Marker
    Error when asked), the axis row `Frame,Time (Seconds),X,Y,Z,W,X,Y,Z`, then one row per frame;
    every row ends with `newline` (Motive's own CRLF by default), the last one too. Only the ID
    cells are quoted: a fake GUID per body, 32 upper-case hex digits, the same for a name every time.
    Numbers have 6 decimals in `units` (positions: half a unit in the 6th decimal, at most 5e-7 m
    in Meters; quaternion components: 5e-7). Time is k / rate_hz, Frame is k.

    names: native body -> rigid body name (DEFAULT_NAMES); only the bodies it names are written.
    A body's cells are blank on its invalid frames and on `occlusions` extra random gaps of
    gap_frames frames (inclusive range) drawn per body from rng. Each valid frame's quaternion is
    written as -q with probability sign_flips (Motive flips between q and -q). Capture Frame Rate
    and Total Frames in Take are the native take's (240 Hz) when the export decimates it, else the
    export's own (a system that captured at rate_hz); 1.24 adds Capture Start Frame 0.

    Returns what was written (Exported), before unit conversion and rounding, with the signs
    as they are in the file."""
    if version not in MOTIVE_VERSIONS:
        raise ValueError(f"version {version!r}: this writer lays out {', '.join(MOTIVE_VERSIONS)}")
    if units not in FROM_METRES:
        raise ValueError(f"units {units!r} are not one of {', '.join(FROM_METRES)}")
    names = dict(DEFAULT_NAMES if names is None else names)
    unknown = [b for b in names if b not in BODIES]
    if unknown:
        raise ValueError(f"names: {unknown[0]!r} is not a body of the format ({', '.join(BODIES)})")
    bad = [n for n in names.values() if any(c in n for c in ',"\r\n')]
    if bad:
        raise ValueError(f"names: rigid body name {bad[0]!r} holds a comma, a quote or a line break")
    rng = np.random.default_rng(0) if rng is None else rng
    scale = FROM_METRES[units]

    t, poses = resample_poses(mocap_df, list(names), rate_hz)
    n = len(t)
    written, cells, header = {}, [], {"Type": [], "Name": [], "ID": [], "component": [], "axis": []}
    for body, rb in names.items():
        p, q, valid = poses[body]
        valid = valid & ~_gaps(n, occlusions, gap_frames, rng)
        flip = (rng.random(n) < sign_flips) & valid
        q = np.where(flip[:, None], -q, q)
        p, q = np.where(valid[:, None], p, np.nan), np.where(valid[:, None], q, np.nan)
        written[body] = (p, q, valid)
        block = [q[:, 1], q[:, 2], q[:, 3], q[:, 0], p[:, 0] * scale, p[:, 1] * scale, p[:, 2] * scale]
        comps = ["Rotation"] * 4 + ["Position"] * 3
        axes = ["X", "Y", "Z", "W", "X", "Y", "Z"]
        if mean_marker_error:
            # Motive's solver residual, in the file's units; a quality figure, not data
            block.append(np.where(valid, np.abs(rng.normal(0.0005, 0.0002, n)) * scale, np.nan))
            comps.append("Mean Marker Error")
            axes.append("")
        guid = '"' + uuid.uuid5(uuid.NAMESPACE_URL, f"motive rigid body {rb}").hex.upper() + '"'
        header["Type"] += ["Rigid Body"] * len(block)
        header["Name"] += [rb] * len(block)
        header["ID"] += [guid] * len(block)
        header["component"] += comps
        header["axis"] += axes
        cells += block

    decimated = abs(MOCAP_HZ / rate_hz - round(MOCAP_HZ / rate_hz)) < 1e-9 and rate_hz <= MOCAP_HZ
    capture_hz, take_frames = (MOCAP_HZ, len(mocap_df)) if decimated else (rate_hz, n)
    meta = [
        ("Format Version", version),
        ("Take Name", take_name),
        ("Take Notes", ""),
        ("Capture Frame Rate", f"{capture_hz:.6f}"),
        ("Export Frame Rate", f"{rate_hz:.6f}"),
        ("Capture Start Time", start_time),
    ]
    if version >= "1.24":
        meta.append(("Capture Start Frame", "0"))
    meta += [
        ("Total Frames in Take", str(take_frames)),
        ("Total Exported Frames", str(n)),
        ("Rotation Type", "Quaternion"),
        ("Length Units", units),
        ("Coordinate Space", "Global"),
    ]
    lines = [",".join(f"{k},{v}" for k, v in meta), ""]
    lines += ["," + ",".join([tag] + header[tag]) for tag in ("Type", "Name", "ID")]
    lines.append(",," + ",".join(header["component"]))
    lines.append("Frame,Time (Seconds)," + ",".join(header["axis"]))
    values = np.stack(cells, axis=1) if cells else np.zeros((n, 0))
    text = np.char.mod(f"%.{DECIMALS}f", np.where(np.isfinite(values), values, 0.0))
    text = np.where(np.isfinite(values), text, "")
    times = np.char.mod(f"%.{DECIMALS}f", np.arange(n) / rate_hz)
    for k in range(n):
        lines.append(",".join([str(k), times[k], *text[k]]))
    with open(path, "w", encoding="utf-8", newline="") as f:
        f.write(newline.join(lines) + newline)
    return Exported(t=t, rate_hz=float(rate_hz), poses=written)


# --- C3D ------------------------------------------------------------------------------------------------


def write_c3d(
    mocap_df: pd.DataFrame,
    path,
    layouts: dict,
    rate_hz: float = 120,
    noise_m: float = 0.0005,
    rng=None,
    *,
    names: dict[str, str] | None = None,
    axes: str = "y_up",
    occlusions: int = 0,
    gap_frames: tuple[int, int] = (1, 10),
) -> Exported:
    """Each body's markers, placed from its pose, as a C3D of 3D points (ezc3d).

    layouts: native body -> its markers in the body frame (metres), a mapping {marker: [x, y, z]}
    or a (k, 3) array (markers M1..Mk). Marker j of a body at frame i is R(q_i) layout_j + p_i in
    the lab frame, plus Gaussian noise of noise_m (standard deviation per axis, from rng), then
    expressed in the capture's axes (`axes`, as the lab file names them: lab = R @ capture) and
    written in mm (POINT:UNITS "mm", float storage, POINT:RATE rate_hz), labelled "<Body>:<Marker>"
    with <Body> from names (DEFAULT_NAMES). A marker is occluded (NaN, residual -1) on its body's
    invalid frames and on `occlusions` extra random gaps per marker.

    Returns the poses the markers were placed from and the markers themselves (lab frame, metres,
    noise included, NaN where occluded), before float32 storage."""
    names = dict(DEFAULT_NAMES if names is None else names)
    rng = np.random.default_rng(0) if rng is None else rng
    rotation = AXES[axes]
    t, poses = resample_poses(mocap_df, list(layouts), rate_hz)
    n = len(t)
    labels, points = [], []
    for body, layout in layouts.items():
        if isinstance(layout, dict):
            marker_names, xyz = list(layout), np.array(list(layout.values()), float)
        else:
            xyz = np.asarray(layout, float)
            marker_names = [f"M{j + 1}" for j in range(len(xyz))]
        p, q, valid = poses[body]
        r = Rotation.from_quat(np.where(valid[:, None], q, [1.0, 0, 0, 0]), scalar_first=True)
        for name, m in zip(marker_names, xyz):
            lab = r.apply(m) + np.where(valid[:, None], p, 0.0) + rng.normal(0.0, noise_m, (n, 3))
            seen = valid & ~_gaps(n, occlusions, gap_frames, rng)
            labels.append(f"{names[body]}:{name}")
            points.append(np.where(seen[:, None], lab, np.nan))
    lab_points = np.stack(points, 1)  # (n, markers, 3)
    capture = lab_points @ rotation  # row vectors: capture = R^T lab
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = np.array([float(rate_hz)])
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c.add_parameter("POINT", "UNITS", "mm")
    data = np.ones((4, len(labels), n))
    data[:3] = np.transpose(capture * 1e3, (2, 1, 0))
    c["data"]["points"] = data
    residuals = np.where(np.isfinite(capture).all(-1).T, 0.0, -1.0)[None]  # as Vicon marks an occlusion
    c["data"]["meta_points"] = {"residuals": residuals, "camera_masks": np.zeros((7, len(labels), n), bool)}
    c.write(str(path))
    return Exported(t=t, rate_hz=float(rate_hz), poses=poses, markers=dict(zip(labels, points)))


# --- the servo PC's log -----------------------------------------------------------------------------------


def servo_clock(t, offset_s: float, drift_ppm: float):
    """The servo PC's clock reading at native (mocap-clock) time t: (t - offset_s) * (1 + drift_ppm 1e-6).

    Sign convention: at mocap time offset_s the servo clock reads 0, and it runs fast by drift_ppm
    (slow if negative). The inverse, what an importer must recover, is
    t = t_servo / (1 + drift_ppm 1e-6) + offset_s: t_servo + offset_s is the mocap time of a servo
    sample up to the drift, the convention of embodied_snap.capture.clock (ClockFit.offset_s)."""
    return (np.asarray(t, float) - offset_s) * (1 + drift_ppm * 1e-6)


def write_servo_log(servo_df: pd.DataFrame, path, offset_s: float, drift_ppm: float = 0.0) -> np.ndarray:
    """The servo log as a plain CSV (the format's columns, t first; t on the servo PC's clock,
    `servo_clock`, to the microsecond; ticks as integers). Returns the t column written."""
    out = servo_df[servo_columns()].copy()
    out["t"] = servo_clock(out["t"].to_numpy(float), offset_s, drift_ppm)
    out.to_csv(path, index=False, float_format="%.6f", lineterminator="\n")
    return out["t"].to_numpy()


# --- the operator's sheet -------------------------------------------------------------------------------


def write_operator_labels(metas, path) -> pd.DataFrame:
    """One session's operator sheet: group_id, attached, retrieved, and base_event_t (the held-base
    push time, on the mocap clock) when any group has one, from each meta.json's labels.

    metas: meta dicts or meta.json paths, all of one session (else ValueError). A label a group does
    not carry is a blank cell; outcomes are written true/false. Returns the table written."""
    metas = [read_meta(m) if isinstance(m, (str, Path)) else m for m in metas]
    sessions = sorted({m.get("session") for m in metas}, key=str)
    if len(sessions) != 1:
        raise ValueError(f"one sheet per session: these groups are from {', '.join(map(str, sessions))}")
    columns = ["group_id", *OPERATOR_LABELS]
    if any(PUSH_LABEL in m.get("labels", {}) for m in metas):
        columns.append(PUSH_LABEL)
    rows = []
    for m in metas:
        labels = m.get("labels", {})
        row = {"group_id": m["group_id"]}
        for k in columns[1:]:
            v = labels.get(k)
            row[k] = "" if v is None else ("true" if v is True else "false" if v is False else repr(float(v)))
        rows.append(row)
    with open(path, "w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, columns, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    return pd.DataFrame(rows, columns=columns)


# --- a whole session, as a lab hands it to `esnap import` -------------------------------------------------

# Three markers per body in its own frame (m): a scalene triangle, so no fit is ambiguous.
LAYOUT = {"m1": [0.02, 0.0, 0.0], "m2": [-0.01, 0.0, 0.025], "m3": [0.0, 0.015, -0.02]}
# Occlusions of up to 3 frames: beside the simulated rig's own dropouts (at most 0.071 s on the
# smoke and quick trees) a gap stays within the gate's 0.1 s, as a lab's takes would have to.
GAP_FRAMES = (1, 3)
SERVO_CLOCK_EVENTS = ("t_preload", "t_slack", "t_s2", "t_s1", "t_release", "t_up", "t_down")


def lab_doc(kind: str, clock: dict, bodies=BODIES) -> dict:
    """A lab file for these exports: each body by its rigid body (`kind` "rigid_body") or its LAYOUT
    markers ("markers"), the servos in order, the arm as config.yaml's rig section gives it."""
    import yaml

    rig = yaml.safe_load((Path(__file__).resolve().parents[1] / "config.yaml").read_text())["rig"]
    spec = {b: {"rigid_body": DEFAULT_NAMES[b]} if kind == "rigid_body" else
            {"markers": {f"{DEFAULT_NAMES[b]}:{m}": xyz for m, xyz in LAYOUT.items()}} for b in bodies}
    return dict(capture=dict(axes="y_up"), bodies=spec, servos=list(range(1, 10)),
                arm={k: rig[k] for k in ("arm_length_m", "tendon_radius_m", "end_effector_m")}, clock=clock)


def export_tree(raw, out, fmt: str = "motive", rate_hz: float = 120, offset_s: float = 0.137, drift_ppm: float = 20.0,
                occlusions: int = 2, noise_m: float = 0.0003, group_ids=None, seed: int = 0) -> list[Path]:
    """A native tree's groups (all, or group_ids) written out as a lab's sessions: per session a
    session file (`<session>.yaml`), an operator sheet (`<session>_labels.csv`), per take a capture
    export (Motive CSV in mm with x, y, z, w quaternions and occlusion gaps, or C3D markers,
    three per body, with noise_m noise) and a servo log on a clock offset_s behind with drift_ppm;
    and `lab.yaml` mapping it all. The servo PC's phase times (SERVO_CLOCK_EVENTS) go into the
    session file on its own clock; the operator's labels are read off the capture's clock (the
    export's: native t minus the first frame's). Returns the session files."""
    import yaml

    raw, out = Path(raw), Path(out)
    (out / "takes").mkdir(parents=True, exist_ok=True)
    index = pd.read_csv(raw / "index.csv", dtype=str)
    if group_ids is not None:
        index = index[index.group_id.isin(list(group_ids))]
    rng = np.random.default_rng(seed)
    lab = lab_doc("markers" if fmt == "c3d" else "rigid_body", dict(sync="none", max_drift_ppm=100, max_offset_s=0.15))
    (out / "lab.yaml").write_text(yaml.safe_dump(lab, sort_keys=False))
    sessions = []
    for session, rows in index.groupby("session", sort=True):
        takes, metas = [], []
        for r in rows.itertuples():
            d = raw / "groups" / r.group_id
            mocap, servo = pd.read_parquet(d / "mocap.parquet"), pd.read_parquet(d / "servo.parquet")
            meta = read_meta(d / "meta.json")
            t0 = float(mocap.t.iloc[0])
            if fmt == "motive":
                name = f"takes/{r.group_id}.csv"
                write_motive_csv(mocap, out / name, rate_hz=rate_hz, units="Millimeters", occlusions=occlusions,
                                 rng=rng, gap_frames=GAP_FRAMES, take_name=f"Take {r.group_id}")
            else:
                name = f"takes/{r.group_id}.c3d"
                write_c3d(mocap, out / name, {b: dict(LAYOUT) for b in BODIES}, rate_hz=rate_hz,
                          noise_m=noise_m, rng=rng, occlusions=occlusions, gap_frames=GAP_FRAMES)
            log = f"takes/{r.group_id}_servo.csv"
            write_servo_log(servo, out / log, offset_s, drift_ppm)
            labels = meta.get("labels", {})
            events = {k: float(servo_clock(labels[k], offset_s, drift_ppm)) for k in SERVO_CLOCK_EVENTS if k in labels}
            take = dict(group_id=r.group_id, evidence_set=r.evidence_set, category=r.category,
                        recorded_at=r.recorded_at, mocap=name, servo=log, program=meta.get("program", {}),
                        events=events)
            if "target" in meta:
                take["target"] = meta["target"]
            takes.append(take)
            seen = dict(meta, labels={k: (v - t0 if k == PUSH_LABEL else v) for k, v in labels.items()})
            metas.append(seen)
        write_operator_labels(metas, out / f"{session}_labels.csv")
        path = out / f"{session}.yaml"
        path.write_text(yaml.safe_dump(dict(session=str(session), labels=f"{session}_labels.csv", takes=takes),
                                       sort_keys=False))
        sessions.append(path)
    return sessions
