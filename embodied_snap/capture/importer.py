"""`esnap import`: a capture session's exports to the recording format, one group per take.

A session file (schemas/session.schema.yaml) says which take is which group; the lab file
(lab.py) says how the capture's bodies and the servo bus map onto the format. Each take becomes a
group in a temporary tree beside the raw directory: its poses in the lab frame, its servo log on
the capture's clock (clock.py), its meta.json with the program, the labels (measured and the
operator's) and how the clocks were matched. The temporary tree then goes through the gate
(verdicts.Verdicts, the same checks as `esnap validate` and the workflow), and only when every
take passed are the groups moved into the raw directory and index.csv rewritten with their rows.
A refused import leaves the raw directory as it was.

Labels. Measured from the recordings: the phase times (`t_preload`, `t_slack`, `t_s2`, `t_s1`,
`t_release`, `t_up`, `t_down`): the servo PC's schedule, moved onto the capture clock; and
`snap_speed_event`: the tip's speed (characterize.mocap.tip_speed, the pipeline's own) reaching
the attachment threshold (config characterize.attach_speed_mps). Observed by the operator (the
session's label sheet): `attached`, `retrieved`, `base_event_t` (on the capture clock, as read off
the capture software), and any other label column the sheet has.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .. import rawformat as RF
from ..characterize.mocap import on_grid, section_bends, tip_speed
from ..files import sha256
from ..io import read_parquet
from ..validate import COVER_TOL_S, ONE_RECORDING_RULE
from .clock import ClockFitOptions, check_drift, estimate_offset, measure_drift
from .errors import CaptureError
from .lab import Lab, read_yaml

SESSION_SCHEMA = Path(__file__).resolve().parents[2] / "schemas" / "session.schema.yaml"
# A take's shared motion can be a few seconds (a calibration burst is 2 s): the clock fit needs
# this much of both signals at its shift, not clock.py's 5 s default for long takes.
MIN_OVERLAP_S = 1.0
# The shared motion is one bend seen twice, but after a release the arm swings on its own (the
# encoders see the tendon pay out, the cameras the swing): a primitive's take peaks at r 0.5-0.8.
MIN_PEAK_CORRELATION = 0.4
# The operator's sheet: outcome labels are true/false, every other label a number (a time).
OUTCOME_LABELS = ("attached", "retrieved", "snap_speed_event")
MEASURED_LABELS = ("snap_speed_event",)  # computed here from the take, never asked of the operator
# What a servo folder's meta.json passes on (esnap deploy's and esnap lab acquire's)
FOLDER_KEYS = ("group_id", "evidence_set", "category", "recorded_at", "program", "target", "goal_timing",
               "manifest_sha256", "plan_sha256", "protocol_version", "axis")
PASSED_ON = ("manifest_sha256", "plan_sha256", "protocol_version")  # provenance kept in the group's meta.json


class ImportRefused(ValueError):
    """One line: `<file>: take <group_id>: <what>`, the file being the export, log or sheet at fault."""


@dataclass
class TakeSpec:
    mocap: Path
    servo: Path
    meta: dict  # group_id, evidence_set, category, session, recorded_at, program, target
    events: dict  # phase -> servo-clock seconds
    labels: dict = field(default_factory=dict)  # the operator's, from the sheet


# --- the session file and the operator's sheet ------------------------------------------------------


def load_session(path) -> list[TakeSpec]:
    path = Path(path)
    doc = read_yaml(path, SESSION_SCHEMA)
    base = path.parent
    takes = []
    for k, t in enumerate(doc["takes"]):
        servo = base / t["servo"]
        meta = dict(session=doc["session"], program=t.get("program", {}))
        events = dict(t.get("events", {}))
        labels = {}
        if servo.is_dir():  # esnap deploy's or esnap lab acquire's group folder: what the servo PC ran
            side = RF.read_meta(servo / "meta.json")
            meta.update({k2: side[k2] for k2 in FOLDER_KEYS if k2 in side})
            # times on the servo clock: the schedule's phases (labels t_*) and what the client logged
            # (events, e.g. a held-base cue); the operator's outcomes as answered at the arm
            side_labels = side.get("labels", {})
            events = {**{k2: v for k2, v in side_labels.items() if k2.startswith("t_")}, **side.get("events", {}),
                      **events}
            labels = {k2: v for k2, v in side_labels.items() if k2 in OUTCOME_LABELS}
        for k2 in ("group_id", "evidence_set", "category", "recorded_at", "target", "goal_timing"):
            if k2 in t:
                meta[k2] = t[k2]
        missing = [k2 for k2 in ("group_id", "evidence_set", "category", "recorded_at") if k2 not in meta]
        if missing:
            raise CaptureError(
                path,
                f"takes.{k}: no {missing[0]}",
                "a take has group_id, evidence_set, category, recorded_at (given, or in its servo folder's meta.json)",
            )
        takes.append(TakeSpec(mocap=_capture_of(path, doc, t, meta["group_id"], k), servo=servo, meta=meta,
                              events=events, labels=labels))
    ids = [t.meta["group_id"] for t in takes]
    dup = next((g for g in ids if ids.count(g) > 1), None)
    if dup:
        raise CaptureError(path, f"group {dup} is given to two takes", "one take per group")
    if "labels" in doc:
        sheet = read_labels(base / doc["labels"], set(ids))
        for t in takes:
            t.labels = {**t.labels, **sheet.get(t.meta["group_id"], {})}
    return takes


CAPTURE_SUFFIXES = (".csv", ".c3d")  # what read_take reads


def _capture_of(path: Path, doc: dict, t: dict, gid: str, k: int) -> Path:
    """The take's export: as given, or the one file in `captures` named by its group id."""
    if "mocap" in t:
        return path.parent / t["mocap"]
    if "captures" not in doc:
        raise CaptureError(
            path,
            f"takes.{k}: no mocap",
            "a take has its capture export (mocap:, or a captures folder holding {gid}.csv or {gid}.c3d)",
        )
    folder = path.parent / doc["captures"]
    found = [folder / f"{gid}{s}" for s in CAPTURE_SUFFIXES if (folder / f"{gid}{s}").is_file()]
    if len(found) != 1:
        what = "no" if not found else "two"
        raise CaptureError(path, f"take {gid}: {what} capture export named {gid}.csv or {gid}.c3d in {folder}",
                           "a take is named by its group id")
    return found[0]


def read_labels(path, group_ids: set[str]) -> dict[str, dict]:
    """The operator's sheet: group_id -> {label: value}; a blank cell is a label not given."""
    path = Path(path)
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise CaptureError(
            path,
            f"not readable as a CSV ({' '.join(str(e).split())})",
            "an operator's sheet is a CSV",
        ) from None
    if "group_id" not in df.columns:
        raise CaptureError(
            path, "no group_id column", "the operator's sheet has group_id, then one column per label"
        )
    out = {}
    for _, row in df.iterrows():
        gid = row["group_id"].strip()
        if gid in out:
            raise ImportRefused(f"{path}: take {gid}: two rows (rule: one row per take)")
        if gid not in group_ids:
            raise ImportRefused(
                f"{path}: take {gid}: not a take of this session (rule: the sheet labels this session's takes)"
            )
        labels = {}
        for k, v in row.items():
            v = v.strip()
            if k == "group_id" or v == "":
                continue
            if k in OUTCOME_LABELS:
                if v.lower() not in ("true", "false"):
                    raise ImportRefused(f"{path}: take {gid}: {k} is {v!r} (rule: outcome labels are booleans)")
                labels[k] = v.lower() == "true"
            else:
                try:
                    labels[k] = float(v)
                except ValueError:
                    raise ImportRefused(
                        f"{path}: take {gid}: {k} is {v!r}, not a number (rule: label times are numbers)"
                    ) from None
                if not np.isfinite(labels[k]):
                    raise ImportRefused(f"{path}: take {gid}: {k} is {v} (rule: label times are numbers)")
        out[gid] = labels
    return out


# --- one take --------------------------------------------------------------------------------------


def read_take(path: Path):
    """A Motive CSV or a C3D, by its suffix."""
    suffix = path.suffix.lower()
    if suffix == ".csv":
        from .motive import read_motive_csv

        return read_motive_csv(path)
    if suffix == ".c3d":
        from .c3d import read_c3d

        return read_c3d(path)
    raise CaptureError(path, f"suffix {path.suffix!r}", "a Motive CSV (.csv) or a C3D (.c3d)")


def mocap_table(take, lab: Lab, max_residual_m: float) -> pd.DataFrame:
    """The take in the format's mocap columns: t from the take's first frame, every body in the
    lab frame, quaternions with w >= 0; a marker fit may leave at most max_residual_m."""
    lo, hi = RF.MOCAP_HZ_RANGE
    if not lo <= take.rate_hz <= hi:
        raise CaptureError(take.path, f"captured at {take.rate_hz:g} Hz", f"capture rate {lo:g}-{hi:g} Hz")
    if len(take.t) < 2:
        raise CaptureError(take.path, f"{len(take.t)} frame(s)", "a take has frames")
    cols = {"t": np.asarray(take.t, float) - float(take.t[0])}
    for body in RF.BODIES:
        if body not in lab.bodies:  # only target may be absent (the lab file's schema)
            p, q, v = np.full((len(take.t), 3), np.nan), np.full((len(take.t), 4), np.nan), np.zeros(len(take.t), bool)
        else:
            p, q, v = lab.body_pose(take, body, max_residual_m)
            q = _hemisphere(q)
        for i, a in enumerate("xyz"):
            cols[f"{body}_{a}"] = np.where(v, p[:, i], np.nan)
        for i, a in enumerate(("qw", "qx", "qy", "qz")):
            cols[f"{body}_{a}"] = np.where(v, q[:, i], np.nan)
        cols[f"{body}_valid"] = v
    return pd.DataFrame(cols)[RF.mocap_columns()]


def _hemisphere(q):
    """q and -q are one rotation: w >= 0, as the simulated rig and the marker fit write them (an
    export may flip between the two from one frame to the next)."""
    q = np.array(q, float)
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def servo_table(path: Path, lab: Lab) -> pd.DataFrame:
    """The servo PC's log in the format's columns (servo column k = bus id lab.servos[k - 1]), on
    its own clock still."""
    if path.is_dir():  # esnap deploy's folder: already in the format's columns
        p = path / "servo.parquet"
        try:
            df = read_parquet(p)
        except (OSError, ValueError) as e:
            raise CaptureError(
                p,
                f"not readable as parquet ({' '.join(str(e).split())})",
                "a parquet servo log",
            ) from None
        return df
    try:
        raw = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise CaptureError(
            path,
            f"not readable as a CSV ({' '.join(str(e).split())})",
            "a servo log is parquet or CSV",
        ) from None
    out = {}
    names = {"t": "t"}
    for k, sid in enumerate(lab.servos, 1):
        names |= {f"{c}_{k}": f"{c}_{sid}" for c in ("goal", "present", "current")}
    column = lab.clock["sync"].get("column") if isinstance(lab.clock["sync"], dict) else None
    if column:
        names["sync"] = column
    missing = [src for src in names.values() if src not in raw.columns]
    if missing:
        raise CaptureError(
            path,
            f"no {missing[0]!r} column",
            "t, goal_<id>, present_<id>, current_<id> for the lab file's servo ids",
        )
    for col, src in names.items():
        v = pd.to_numeric(raw[src], errors="coerce")
        if v.isna().any():
            raise CaptureError(
                path,
                f"a blank or non-numeric cell in {src!r} (row {int(v.isna().idxmax()) + 2})",
                "every cell a number",
            )
        out[col] = v.to_numpy()
    df = pd.DataFrame(out)
    for c in df.columns:
        if c.startswith(("goal_", "present_")):
            if not (df[c] == df[c].round()).all():  # noqa: SIM102
                raise CaptureError(path, f"{c!r} holds a fraction", "ticks are integers")
            df[c] = df[c].round().astype("int64")
    return df[RF.servo_columns() + (["sync"] if column else [])]


def clock_signals(mocap: pd.DataFrame, servo: pd.DataFrame, max_gap_s: float):
    """(section, mocap bend rate, servo tendon rate): of the section whose servos moved most (S3 in
    a primitive, whose tendons carry every section's share; the burst's own in a calibration), its
    bend rate from the tracked frames (characterize.mocap.section_bends) and the rate of its tendon
    travel magnitude sqrt(2/3 sum_k d_k^2) from the servos' measured positions, d_k = present_k
    minus its first value. For tendons at 120 deg that magnitude is r * theta whatever the bend's
    direction, so both are the same bend's rate, one seen by the cameras, one by the encoders."""
    t_s = servo["t"].to_numpy(float)
    travel = []
    for s in (1, 2, 3):
        d = np.stack([servo[f"present_{RF.servo_id(s, k)}"].to_numpy(float) for k in (1, 2, 3)], 1)
        travel.append(np.sqrt(2 / 3 * ((d - d[0]) ** 2).sum(1)))
    s = int(np.argmax([np.ptp(x) for x in travel]))
    # the format's w >= 0 flips a quaternion's sign wherever a body turns through half a turn:
    # section_bends (mocap.track) makes the signs continuous before it bridges a dropout
    theta, _ = section_bends(mocap, max_gap_s)
    return s + 1, np.gradient(theta[:, s], mocap["t"].to_numpy(float)), np.gradient(travel[s], t_s)


def align(mocap: pd.DataFrame, servo: pd.DataFrame, lab: Lab, src, max_gap_s: float, frame_s: float):
    """(servo log with t on the capture clock, the clock record for meta.json)."""
    t_s = servo["t"].to_numpy(float)
    t_m = mocap["t"].to_numpy(float)
    sync = lab.clock["sync"]
    limit = lab.clock["max_drift_ppm"] * 1e-6
    if isinstance(sync, dict) and "event_time_s" in sync:
        offset, rec = (
            float(sync["event_time_s"]),
            dict(
                method=f"sync event: the servo log's t = 0 is the capture's {sync['event_time_s']:g} s",
                offset_s=float(sync["event_time_s"]),
            ),
        )
        rate = 0.0
    elif isinstance(sync, dict) and "column" in sync:  # a hardware-stamped capture time per sample
        lag = servo["sync"].to_numpy(float) - t_s
        slope, offset = np.polyfit(t_s, lag, 1) if len(t_s) > 2 else (0.0, float(lag.mean()))
        rec = dict(
            method=f"sync column {sync['column']!r}: each sample's capture-clock time",
            offset_s=float(offset),
            uncertainty_s=float(np.std(lag - (offset + slope * t_s))),
            drift=float(slope),
            sync="column",
        )
        check_drift(slope, limit, src)
        offset, rate = float(offset), float(slope)  # at t_servo_ref 0, the line's own origin
    else:
        section, motion, command = clock_signals(mocap, servo, max_gap_s)
        options = ClockFitOptions(
            max_shift_s=lab.clock["max_offset_s"],
            guess_s=t_m[0] - t_s[0],
            min_overlap_s=MIN_OVERLAP_S,
            min_peak_correlation=MIN_PEAK_CORRELATION,
            max_gap_s=max_gap_s,
            motion_name=f"the S{section} bend rate",
            command_name=f"the S{section} tendon travel rate",
        )
        fit = estimate_offset(t_m, motion, t_s, command, options, source=src)
        offset, rec = fit.offset_s, dict(fit.to_meta(), sync="none")
        rate = 0.0
        # Drift moves the offset by (drift x duration): at the limit, over a take of a few
        # seconds, far less than a frame, and the fit's thirds would differ by the physics of
        # their phases (preload, release) rather than by the clocks. It is measured only on a
        # take long enough for a drift at the limit to move the offset by a capture frame.
        span = min(t_m[-1], t_s[-1] + fit.offset_s) - max(t_m[0], t_s[0] + fit.offset_s)
        if span * limit < frame_s:
            rec["drift"] = None
            rec["drift_note"] = (
                f"not measured: over {span:.1f} s a drift of {lab.clock['max_drift_ppm']:g} ppm moves "
                f"the offset by {span * limit * 1e3:.2f} ms, under one frame ({frame_s * 1e3:.2f} ms)"
            )
        else:
            drift = measure_drift(t_m, motion, t_s, command, options, source=src)
            rec.update(drift=drift.rate, drift_uncertainty=drift.uncertainty)
            check_drift(drift.rate, limit, src)
            rate = drift.rate
            rec["t_servo_ref"] = 0.5 * (drift.t_first + drift.t_last)
    rec["drift_applied"] = rate
    ref = rec.get("t_servo_ref", 0.0)
    out = servo[RF.servo_columns()].copy()
    out["t"] = t_s + offset + rate * (t_s - ref)
    return out, rec, lambda t: t + offset + rate * (t - ref)


def build_group(spec: TakeSpec, lab: Lab, config: dict) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    """(meta, mocap, servo) of one take, in the recording format."""
    max_gap_s = config["resample"]["max_gap_s"]
    take = read_take(spec.mocap)
    mocap = mocap_table(take, lab, config["capture"]["max_marker_residual_mm"] * 1e-3)
    servo_raw = servo_table(spec.servo, lab)
    if len(servo_raw) < 2 or not np.all(np.diff(servo_raw["t"].to_numpy(float)) > 0):
        raise CaptureError(spec.servo, "t is not strictly increasing", "t strictly increasing")
    servo, clock, to_capture = align(mocap, servo_raw, lab, spec.servo, max_gap_s, 1 / take.rate_hz)
    # Both logs over the time both cover, as the gate wants the servo log around the mocap (to
    # within half its tolerance, so a frame at the edge never decides the rule)
    t_s = servo["t"].to_numpy(float)
    a, b = t_s[0] - COVER_TOL_S / 2, t_s[-1] + COVER_TOL_S / 2
    keep = ((mocap["t"] >= a) & (mocap["t"] <= b)).to_numpy()
    if keep.sum() < 2:
        raise CaptureError(
            spec.servo,
            f"on the capture clock it spans {t_s[0]:.3f}-{t_s[-1]:.3f} s and the take "
            f"{mocap['t'].iloc[0]:.3f}-{mocap['t'].iloc[-1]:.3f} s",
            "the servo log overlaps the take",
        )
    mocap = mocap[keep].reset_index(drop=True)
    m0, m1 = mocap["t"].iloc[0], mocap["t"].iloc[-1]
    # the sync-reads from the last one before the mocap's first frame to the first after its last
    i0 = max(int(np.searchsorted(t_s, m0, side="right")) - 1, 0)
    i1 = min(int(np.searchsorted(t_s, m1, side="left")) + 1, len(t_s))
    servo = servo.iloc[i0:i1].reset_index(drop=True)

    labels = {k: round(float(to_capture(v)), 4) for k, v in spec.events.items()}
    v = tip_speed(on_grid(mocap), max_gap_s)
    (measured,) = MEASURED_LABELS
    labels[measured] = bool(np.isfinite(v).any() and np.nanmax(v) >= config["characterize"]["attach_speed_mps"])
    labels.update(spec.labels)
    meta = dict(
        format_version=RF.FORMAT_VERSION,
        source="rig",
        **{k: spec.meta[k] for k in ("group_id", "evidence_set", "category", "session", "recorded_at")},
    )
    meta["program"] = spec.meta.get("program", {})
    for k in ("target", "goal_timing"):
        if k in spec.meta:
            meta[k] = spec.meta[k]
    meta.update(base_and_axis(mocap))
    meta["labels"] = labels
    meta["clock"] = clock
    meta["capture"] = dict(
        file=spec.mocap.name,
        sha256=sha256(spec.mocap),
        rate_hz=float(take.rate_hz),
        units=take.units,
        servo_log=spec.servo.name,
        lab=lab.path.name,
    )
    meta.update({k: spec.meta[k] for k in PASSED_ON if k in spec.meta})
    return meta, mocap, servo


def base_and_axis(mocap: pd.DataFrame) -> dict:
    """The mount's pose (mean of the base's valid samples; its quaternion's sign already continuous)
    and the hanging axis, the base frame's -Y in the lab frame."""
    from ..quat import qrotate

    v = mocap["base_valid"].to_numpy(bool)
    if not v.any():
        return dict(base=dict(pos=[0.0, 0.0, 0.0], quat=[1.0, 0.0, 0.0, 0.0]), axis=[0.0, -1.0, 0.0])
    p = mocap.loc[v, ["base_x", "base_y", "base_z"]].to_numpy(float).mean(0)
    q = mocap.loc[v, ["base_qw", "base_qx", "base_qy", "base_qz"]].to_numpy(float).mean(0)
    q = q / np.linalg.norm(q) * (1 if q[0] >= 0 else -1)
    axis = qrotate(q, np.array([0.0, -1.0, 0.0]))
    return dict(
        base=dict(pos=[float(x) for x in p], quat=[float(x) for x in q]),
        axis=[float(x) for x in axis / np.linalg.norm(axis)],
    )


def check_not_imported(specs, raw: Path, group_ids) -> None:
    """A take is imported once: refused when its export's bytes are those of the take a group of
    raw was imported from (its meta.json's capture.sha256), whatever the group's id, or of another
    take of this session."""
    held = {}  # an export's sha256 -> where it already is
    for gid in sorted(group_ids):
        try:
            sha = RF.read_meta(RF.group_paths(raw, gid)["meta"]).get("capture", {}).get("sha256")
        except (OSError, ValueError, AttributeError):
            continue  # not an imported group, or a broken one: the gate names it
        if sha:
            held.setdefault(sha, f"already imported as group {gid} in {raw}")
    for s in specs:
        try:
            sha = sha256(s.mocap)
        except OSError:
            continue  # building the take says what is wrong with it
        if sha in held:
            raise ImportRefused(f"{s.mocap}: take {s.meta['group_id']}: {held[sha]} (rule: {ONE_RECORDING_RULE})")
        held[sha] = f"the same export as take {s.meta['group_id']} of this session"


# --- the session ------------------------------------------------------------------------------------


def import_session(session_path, lab: Lab, raw_dir, config: dict, progress=None) -> list[dict]:
    """Every take of the session into raw_dir, or none: returns the index rows added."""
    from ..validate import Limits, RecordingError, read_index
    from ..verdicts import Verdicts

    raw = Path(raw_dir)
    specs = load_session(session_path)
    pattern = Limits.from_config(config).group_id_pattern
    existing = read_index(raw, pattern) if (raw / "index.csv").exists() else None
    have = set(existing.group_id) if existing is not None else set()
    have |= {p.name for p in (raw / "groups").glob("*")} if (raw / "groups").is_dir() else set()
    check_not_imported(specs, raw, have)
    for s in specs:
        if s.meta["group_id"] in have:
            raise ImportRefused(
                f"{raw}: take {s.meta['group_id']}: already in {raw} (rule: an import never "
                "overwrites a group; remove it first to re-import)"
            )
    # beside the tree (one filesystem, so the groups move in by rename), in the nearest folder that
    # exists: a refused import makes no folder
    anchor = raw.absolute().parent
    while not anchor.is_dir():
        anchor = anchor.parent
    tmp = Path(tempfile.mkdtemp(prefix=".esnap-import-", dir=anchor))
    try:
        rows = []
        for s in progress(specs) if progress else specs:
            gid = s.meta["group_id"]
            try:
                meta, mocap, servo = build_group(s, lab, config)
            except CaptureError as e:
                raise ImportRefused(f"{e.path}: take {gid}: {e.line}") from None
            (tmp / "groups" / gid).mkdir(parents=True)
            RF.write_group(tmp, meta, mocap, servo)
            rows.append({**{k: meta[k] for k in RF.INDEX_COLUMNS[:5]}, "n_mocap": len(mocap), "n_servo": len(servo)})
        RF.write_index(rows, tmp / "index.csv")
        by_id = {s.meta["group_id"]: s for s in specs}
        try:
            Verdicts(tmp, Limits.from_config(config), {r["group_id"]: r for r in rows}, None).check(list(by_id))
            read_index(tmp, pattern)
        except RecordingError as e:
            s = by_id.get(e.group_id)
            src = (
                {"mocap.parquet": s.mocap, "servo.parquet": s.servo}.get(Path(e.path).name, session_path)
                if s
                else e.path
            )
            raise ImportRefused(f"{src}: take {e.group_id}: {e.what} (rule: {e.rule})") from None
        (raw / "groups").mkdir(parents=True, exist_ok=True)
        for r in rows:
            os.replace(tmp / "groups" / r["group_id"], raw / "groups" / r["group_id"])
        old = existing.to_dict("records") if existing is not None else []
        RF.write_index(old + rows, raw / "index.csv")
        return rows
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
