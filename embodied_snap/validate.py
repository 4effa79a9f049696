"""Validation of raw recordings against the rig format (docs/design.md section 2, rawformat.py).

Table checks are pandera schemas, one per file; what spans files (meta.json against its folder
and index.csv, the servo log covering the mocap, row counts) is checked in plain code after them.
The first broken rule raises a RecordingError whose message is one line naming the file, the
group and the rule, so a workflow log shows at once which recording to fix.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pandera.pandas as pa
import pyarrow as pa_arrow
from pandera.errors import SchemaError, SchemaErrorReason, SchemaErrors

from .io import parquet_rows, read_parquet
from .rawformat import (
    BODIES,
    CATEGORIES,
    EVIDENCE_SETS,
    GROUP_FILES,
    INDEX_COLUMNS,
    MOCAP_HZ,
    POSE_FIELDS,
    SERVO_HZ,
    SERVO_IDS,
    group_dir,
    group_paths,
    mocap_columns,
    servo_columns,
)

# Lab-frame coordinates of a mocap volume are a few metres at most; the same arm in millimetres
# reads hundreds to thousands, so this bound catches a unit slip.
MAX_ABS_POSITION_M = 5.0
# Motion capture exports unit quaternions; float32 round-off stays far below this.
QUAT_NORM_TOL = 1e-3
# Mocap is hardware-clocked (tight); the servo sync-read loop is jittered (loose).
MOCAP_RATE_TOL = 0.01
SERVO_RATE_TOL = 0.3
# XM430-W350-R in extended position mode: +-256 revolutions of 4096 ticks.
TICK_LIMIT = 1_048_575
# XM430 current limit (1193 units of 2.69 mA); a log in raw units or amperes falls outside.
CURRENT_LIMIT_MA = 3300.0
# The servo log may start or end this much inside the mocap span (one sync-read or a few).
COVER_TOL_S = 0.05
# Keys every meta.json carries whatever the evidence set (the rest depends on the program).
META_KEYS = ("group_id", "evidence_set", "category", "session")
# Bodies the state x_t is built from; the target is tracked but not part of x_t.
TRACKED_BODIES = ("base", "s1", "s2", "tip")


class RecordingError(ValueError):
    """A raw recording breaks the format: one line, `<file>: group <gid>: <what> (rule: <rule>)`."""

    def __init__(self, path, group_id, what, rule):
        self.path, self.group_id, self.what, self.rule = str(path), str(group_id), what, rule
        msg = f"{path}: group {group_id}: {what} (rule: {rule})"
        super().__init__(" ".join(msg.split()))  # one line whatever the pieces hold

    def __reduce__(self):  # picklable across worker processes
        return (type(self), (self.path, self.group_id, self.what, self.rule))


# --- schemas -------------------------------------------------------------------------------


def _strictly_increasing(s: pd.Series) -> pd.Series:
    return pd.Series(np.diff(s.to_numpy(), prepend=-np.inf) > 0, index=s.index)


_IN_METRES = pa.Check.in_range(-MAX_ABS_POSITION_M, MAX_ABS_POSITION_M, name="positions in metres")
_INCREASING = pa.Check(_strictly_increasing, name="t strictly increasing", error="t does not increase")
_KNOWN_SET = pa.Check.isin(EVIDENCE_SETS, name="known evidence set", error="not a known evidence set")


def _rate_check(hz: float, tol: float, name: str) -> pa.Check:
    # The median step is robust to jitter and to a few lost samples.
    return pa.Check(
        lambda df: len(df) > 1 and abs(np.median(np.diff(df["t"].to_numpy())) * hz - 1.0) <= tol,
        name=name,
        error=f"median sample interval is not 1/{hz:g} s (+-{tol:.0%})",
    )


def _body_checks(b: str) -> list[pa.Check]:
    pos = [f"{b}_{f}" for f in POSE_FIELDS[:3]]
    quat = [f"{b}_{f}" for f in POSE_FIELDS[3:]]
    v = f"{b}_valid"
    return [
        # Invalid samples may hold anything (NaN, stale values); valid ones must be complete.
        pa.Check(
            lambda df: ~df[v] | np.isfinite(df[pos + quat].to_numpy()).all(axis=1),
            name=f"valid {b} samples complete",
            error=f"{b} marked valid but its pose has NaN/inf",
        ),
        pa.Check(
            lambda df: ~df[v] | (np.abs(np.linalg.norm(df[quat].to_numpy(), axis=1) - 1) <= QUAT_NORM_TOL),
            name=f"unit {b} quaternions",
            error=f"{b} quaternion norm differs from 1 by more than {QUAT_NORM_TOL:g}",
        ),
    ]


def _mocap_schema() -> pa.DataFrameSchema:
    cols = {"t": pa.Column("float64", _INCREASING)}
    for b in BODIES:
        for f in POSE_FIELDS:
            # NaN allowed: tracking lost. Quaternions are checked as a whole (unit norm) below.
            in_m = [_IN_METRES] if f in "xyz" else []
            cols[f"{b}_{f}"] = pa.Column("float64", in_m, nullable=True)
        cols[f"{b}_valid"] = pa.Column("bool")
    checks = [_rate_check(MOCAP_HZ, MOCAP_RATE_TOL, f"mocap rate {MOCAP_HZ:g} Hz")]
    for b in BODIES:
        checks += _body_checks(b)
    assert list(cols) == mocap_columns()
    return pa.DataFrameSchema(cols, checks=checks, strict=True)


def _servo_schema() -> pa.DataFrameSchema:
    ticks = [
        pa.Check(
            pd.api.types.is_integer_dtype, name="ticks are integers", error="ticks not stored as integers"
        ),
        pa.Check.in_range(-TICK_LIMIT, TICK_LIMIT, name="ticks in range"),
    ]
    current = [
        pa.Check(pd.api.types.is_numeric_dtype, name="current is numeric", error="current not numeric"),
        pa.Check.in_range(-CURRENT_LIMIT_MA, CURRENT_LIMIT_MA, name="current in mA"),
    ]
    cols = {"t": pa.Column("float64", _INCREASING)}
    for i in SERVO_IDS:
        cols[f"goal_{i}"] = pa.Column(None, ticks)
        cols[f"present_{i}"] = pa.Column(None, ticks)
        cols[f"current_{i}"] = pa.Column(None, current)
    assert list(cols) == servo_columns()
    return pa.DataFrameSchema(
        cols, checks=[_rate_check(SERVO_HZ, SERVO_RATE_TOL, f"servo rate about {SERVO_HZ:g} Hz")], strict=True
    )


def _known_category(df: pd.DataFrame) -> pd.Series:
    return pd.Series(
        [c in CATEGORIES.get(e, ()) for e, c in zip(df.evidence_set, df.category)], index=df.index
    )


_KNOWN_CATEGORY = pa.Check(
    _known_category, name="known category", error="category not one of its evidence set's"
)
_NONEMPTY = pa.Check.str_length(min_value=1, name="non-empty")

# meta.json is validated as a one-row frame; keys beyond META_KEYS depend on the program.
META_SCHEMA = pa.DataFrameSchema(
    {
        "group_id": pa.Column(str, _NONEMPTY),
        "evidence_set": pa.Column(str, _KNOWN_SET),
        "category": pa.Column(str),
        "session": pa.Column(str, _NONEMPTY),
    },
    checks=[_KNOWN_CATEGORY],
)

INDEX_SCHEMA = pa.DataFrameSchema(
    {
        "group_id": pa.Column(
            str,
            pa.Check.str_matches(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$", name="group id is a folder name"),
            unique=True,
        ),
        "evidence_set": pa.Column(str, _KNOWN_SET),
        "category": pa.Column(str),
        "session": pa.Column(str, _NONEMPTY),
        "recorded_at": pa.Column(
            str,
            pa.Check(
                lambda s: pd.to_datetime(s, errors="coerce", format="ISO8601").notna(),
                name="recorded_at is ISO 8601",
                error="not an ISO 8601 time",
            ),
        ),
        "n_mocap": pa.Column("int64", pa.Check.ge(0, name="row count >= 0"), coerce=True),
        "n_servo": pa.Column("int64", pa.Check.ge(0, name="row count >= 0"), coerce=True),
    },
    checks=[_KNOWN_CATEGORY],
    strict=True,
    ordered=True,
)
assert list(INDEX_SCHEMA.columns) == list(INDEX_COLUMNS)

MOCAP_SCHEMA = _mocap_schema()
SERVO_SCHEMA = _servo_schema()


def _first_row(err: SchemaError):
    fc = err.failure_cases
    if isinstance(fc, pd.DataFrame) and "index" in fc and fc["index"].notna().any():
        return fc["index"].dropna().iloc[0]
    return None


def _first_case(err: SchemaError):
    fc = err.failure_cases
    if isinstance(fc, pd.DataFrame) and "failure_case" in fc and len(fc):
        return fc["failure_case"].iloc[0]
    return fc


def _run_schema(schema, df, path, group, noun="column"):
    """Validate; on failure raise a RecordingError for the first broken rule.

    `group` is the group id, or a callable row-index -> group id (index.csv, one group a row).
    """
    try:
        return schema.validate(df)
    except SchemaErrors as errs:  # pandera raises these for strict/coerce even when not lazy
        err = errs.schema_errors[0]
    except SchemaError as e:
        err = e
    col = getattr(err.schema, "name", None) if isinstance(err.schema, pa.Column) else None
    row = _first_row(err)
    code = err.reason_code
    if code == SchemaErrorReason.COLUMN_NOT_IN_DATAFRAME:
        what, rule = f"{noun} '{_first_case(err)}' missing", f"required {noun}s"
    elif code == SchemaErrorReason.COLUMN_NOT_IN_SCHEMA:
        what, rule = f"unexpected {noun} '{_first_case(err)}'", f"no extra {noun}s"
    elif code == SchemaErrorReason.COLUMN_NOT_ORDERED:
        what, rule = f"{noun}s out of order: {list(df.columns)}", f"{noun} order"
    elif code in (SchemaErrorReason.WRONG_DATATYPE, SchemaErrorReason.DATATYPE_COERCION):
        what = f"{noun} '{col}' is {df[col].dtype}, expected {err.schema.dtype}"
        rule = f"{noun} dtype"
    elif code == SchemaErrorReason.SERIES_CONTAINS_NULLS:
        what, rule = f"{noun} '{col}' has empty values", f"{noun} '{col}' not null"
    elif code == SchemaErrorReason.SERIES_CONTAINS_DUPLICATES:
        what, rule = f"{noun} '{col}' repeats '{_first_case(err)}'", f"unique {col}"
    else:
        # Named checks carry the rule; their `error` (or the built-in's own) says what failed.
        rule = getattr(err.check, "name", None) or str(code)
        what = getattr(err.check, "error", None) or "fails"
        if col:
            what = f"{noun} '{col}': {what}"
        if row is not None:
            what += f" at row {row}"
            if "t" in df:
                what += f" (t={df['t'].loc[row]:.4f} s)"
            case = _first_case(err)
            if col and np.isscalar(case):
                what += f": {case.item() if isinstance(case, np.generic) else case!r}"
    if callable(group):
        group = group(row) if row is not None else "-"
    raise RecordingError(path, group, what, rule) from None


# --- readers that turn read failures into RecordingErrors ------------------------------------


def _read_parquet(path: Path, gid: str) -> pd.DataFrame:
    if not path.exists():
        raise RecordingError(path, gid, "missing", "group has its three files")
    try:
        return read_parquet(path)
    except (OSError, ValueError, pa_arrow.ArrowException) as e:
        raise RecordingError(path, gid, f"cannot be read: {e}", "readable parquet") from None


def _parquet_rows(path: Path, gid: str) -> int:
    try:
        return parquet_rows(path)  # footer only: fast on a thousand groups
    except (OSError, ValueError, pa_arrow.ArrowException) as e:
        raise RecordingError(path, gid, f"cannot be read: {e}", "readable parquet") from None


def _read_meta(path: Path, gid: str, index_row: dict | None = None) -> dict:
    if not path.exists():
        raise RecordingError(path, gid, "missing", "group has its three files")
    try:
        meta = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise RecordingError(path, gid, f"not JSON: {e}", "meta.json is JSON") from None
    if not isinstance(meta, dict):
        raise RecordingError(
            path, gid, f"holds a {type(meta).__name__}, not an object", "meta.json is an object"
        )
    _run_schema(
        META_SCHEMA, pd.DataFrame([{k: meta[k] for k in META_KEYS if k in meta}]), path, gid, noun="key"
    )
    if meta["group_id"] != gid:
        raise RecordingError(
            path, gid, f"group_id '{meta['group_id']}' in folder '{gid}'", "meta group_id matches folder"
        )
    for k in META_KEYS[1:]:
        if index_row is not None and k in index_row and str(index_row[k]) != meta[k]:
            raise RecordingError(
                path,
                gid,
                f"{k} '{meta[k]}' but index.csv says '{index_row[k]}'",
                "meta.json agrees with index.csv",
            )
    return meta


def _file_entry(path: Path) -> dict:
    data = path.read_bytes()
    return {"path": str(path), "sha256": hashlib.sha256(data).hexdigest(), "bytes": len(data)}


# --- public API ------------------------------------------------------------------------------


def validate_group(raw_dir, group_id: str, index_row: dict | None = None) -> dict:
    """Check one group's three files; return its raw-manifest entry (sha256 per file)."""
    paths = group_paths(raw_dir, group_id)
    meta = _read_meta(paths["meta"], group_id, index_row)
    mocap = _read_parquet(paths["mocap"], group_id)
    _run_schema(MOCAP_SCHEMA, mocap, paths["mocap"], group_id)
    servo = _read_parquet(paths["servo"], group_id)
    _run_schema(SERVO_SCHEMA, servo, paths["servo"], group_id)

    # Every 50 Hz state needs servo positions, so the servo log must span the mocap.
    tm, ts = mocap["t"].to_numpy(), servo["t"].to_numpy()
    if ts[0] > tm[0] + COVER_TOL_S or ts[-1] < tm[-1] - COVER_TOL_S:
        raise RecordingError(
            paths["servo"],
            group_id,
            f"servo log spans {ts[0]:.3f}..{ts[-1]:.3f} s, mocap {tm[0]:.3f}..{tm[-1]:.3f} s",
            "servo log covers mocap",
        )
    if index_row is not None:
        for key, n, name in (
            ("n_mocap", len(mocap), "mocap.parquet"),
            ("n_servo", len(servo), "servo.parquet"),
        ):
            if key in index_row and int(index_row[key]) != n:
                raise RecordingError(
                    Path(raw_dir) / "index.csv",
                    group_id,
                    f"{key} {index_row[key]} but {name} has {n} rows",
                    f"{key} matches {name}",
                )
    valid = mocap[[f"{b}_valid" for b in TRACKED_BODIES]].all(axis=1)
    return {
        "group_id": group_id,
        "evidence_set": meta["evidence_set"],
        "category": meta["category"],
        "session": meta["session"],
        "files": {name: _file_entry(group_dir(raw_dir, group_id) / name) for name in GROUP_FILES},
        "n_mocap": int(len(mocap)),
        "n_servo": int(len(servo)),
        "duration_s": float(tm[-1] - tm[0]),
        "mocap_valid_fraction": float(valid.mean()),
    }


def validate_index(raw_dir) -> pd.DataFrame:
    """Check index.csv against the group folders (cheap: parquet footers and meta.json only)."""
    path = Path(raw_dir) / "index.csv"
    if not path.exists():
        raise RecordingError(path, "-", "missing", "raw_data/index.csv lists every group")
    try:
        raw = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, ValueError) as e:
        raise RecordingError(path, "-", f"cannot be read: {e}", "readable csv") from None
    gid_of = lambda row: raw["group_id"].iloc[int(row)] if "group_id" in raw else "-"  # noqa: E731
    index = _run_schema(INDEX_SCHEMA, raw, path, gid_of)

    groups = Path(raw_dir) / "groups"
    on_disk = (
        sorted(p.name for p in groups.iterdir() if p.is_dir() and not p.name.startswith("."))
        if groups.is_dir()
        else []
    )
    listed = set(index.group_id)
    for gid in on_disk:
        if gid not in listed:
            raise RecordingError(
                groups / gid, gid, "folder has no row in index.csv", "every group has an index row"
            )
    for row in index.to_dict("records"):
        gid, paths = row["group_id"], group_paths(raw_dir, row["group_id"])
        for p in paths.values():
            if not p.exists():
                raise RecordingError(p, gid, "missing (listed in index.csv)", "index row has its files")
        for key, p in (("n_mocap", paths["mocap"]), ("n_servo", paths["servo"])):
            n = _parquet_rows(p, gid)
            if n != row[key]:
                raise RecordingError(
                    path, gid, f"{key} {row[key]} but {p.name} has {n} rows", f"{key} matches {p.name}"
                )
        _read_meta(paths["meta"], gid, row)
    return index


def validate_shard(raw_dir, group_ids: list[str], index: pd.DataFrame) -> list[dict]:
    """Manifest entries of a shard's groups, each checked against its index.csv row."""
    rows = {r["group_id"]: r for r in index.to_dict("records")}
    out = []
    for gid in group_ids:
        if gid not in rows:
            raise RecordingError(
                Path(raw_dir) / "index.csv", gid, "no row in index.csv", "every group has an index row"
            )
        out.append(validate_group(raw_dir, gid, rows[gid]))
    return out
