"""The rig format's tables as schemas, and readers that turn read failures into one line.

Each file of a recording has a pandera schema (mocap_schema, servo_schema, meta_schema,
index_schema); `run_schema` raises a RecordingError for the first rule a table breaks, naming the
file, the group and the rule. A fast pre-check passes a good table without pandera, which is
imported only when a schema is built: on a table the pre-check doubts, to name the broken rule.
The rules that span files or need limits from config (dropouts, speeds, labels, format version)
are the gate's, in validate.py.
"""

from __future__ import annotations

import hashlib
import json
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
import pyarrow as pa_arrow

from .io import parquet_from_bytes, parquet_rows, read_parquet
from .rawformat import (
    BODIES,
    CATEGORIES,
    EVIDENCE_SETS,
    INDEX_COLUMNS,
    MOCAP_HZ_RANGE,
    MOCAP_RATE_RULE,
    POSE_FIELDS,
    SERVO_HZ,
    SERVO_IDS,
    RecordingError,
    mocap_columns,
    servo_columns,
)

if TYPE_CHECKING:
    from pandera.errors import SchemaError

# Where the capture's origin lies is the lab's business (a body 5 m from it is as good as one at
# it); what the format fixes is the unit, and the arm shows it: every body stays within reach of
# the base, under a metre (rig.arm_length_m plus the end effector) in metres, hundreds in
# millimetres. Checked per frame on the samples where the body and the base are both valid.
MAX_FROM_BASE_M = 2.0
FROM_BASE_RULE = f"bodies within {MAX_FROM_BASE_M:g} m of the base"
# Motion capture exports unit quaternions; float32 round-off stays far below this.
QUAT_NORM_TOL = 1e-3
# Mocap is hardware-clocked (tight); the servo sync-read loop is jittered (loose).
MOCAP_RATE_TOL = 0.01
# The ends of MOCAP_HZ_RANGE are included up to float round-off of the timestamps (a relative
# 1e-6 of the rate: a 100 Hz clock counted from t ~ 1e7 s still reads 100 Hz).
_RANGE_ROUNDOFF = 1e-6
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
# Group ids are folder names (raw_data.group_id_pattern overrides it): no separators, no leading dot.
GROUP_ID_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$"


# --- schemas -------------------------------------------------------------------------------
# pandera is imported where a schema is built, not with this module: its import and first
# schema cost 0.26 s of every workflow parse (index.csv) and gate job, and a good table never
# needs one (the pre-checks below).


def _strictly_increasing(s: pd.Series) -> pd.Series:
    return pd.Series(np.diff(s.to_numpy(), prepend=-np.inf) > 0, index=s.index)


def _increasing():
    import pandera.pandas as pa

    return pa.Check(_strictly_increasing, name="t strictly increasing", error="t does not increase")


def _known_set():
    import pandera.pandas as pa

    return pa.Check.isin(EVIDENCE_SETS, name="known evidence set", error="not a known evidence set")


def _rate_check(hz: float, tol: float, name: str):
    import pandera.pandas as pa

    # The median step is robust to jitter and to a few lost samples.
    return pa.Check(
        lambda df: len(df) > 1 and abs(np.median(np.diff(df["t"].to_numpy())) * hz - 1.0) <= tol,
        name=name,
        error=f"median sample interval is not 1/{hz:g} s (+-{tol:.0%})",
    )


def _mocap_rate_in_range(t: np.ndarray, hz_range=MOCAP_HZ_RANGE) -> bool:
    """The rate the recording's own clock gives, 1 / median interval, lies in hz_range (Hz)."""
    if len(t) < 2:
        return False
    m = float(np.median(np.diff(t)))
    lo, hi = hz_range
    return bool(m > 0 and lo * (1 - _RANGE_ROUNDOFF) <= 1.0 / m <= hi * (1 + _RANGE_ROUNDOFF))


def _mocap_intervals_constant(t: np.ndarray, tol: float = MOCAP_RATE_TOL) -> bool:
    """A constant time base: every interval is a whole number k >= 1 of the median interval m,
    to within tol * m. k > 1 is rows missing (a hole, bounded in seconds by the gate's hole rule),
    not a change of rate; anything else (jitter, a rate that changes) is refused."""
    if len(t) < 2:
        return False
    dt = np.diff(t)
    m = np.median(dt)
    if not m > 0:  # NaN included
        return False
    with np.errstate(invalid="ignore", over="ignore"):  # an inf interval is refused, quietly
        k = np.maximum(np.rint(dt / m), 1.0)
        return bool((np.abs(dt - k * m) <= tol * m).all())


def _mocap_rate_checks() -> list:
    """The mocap time base (rule MOCAP_RATE_RULE): its rate in range and its intervals constant."""
    import pandera.pandas as pa

    lo, hi = MOCAP_HZ_RANGE
    return [
        pa.Check(
            lambda df: _mocap_rate_in_range(df["t"].to_numpy()),
            name=MOCAP_RATE_RULE,
            error=f"median sample interval is not 1/{hi:g}..1/{lo:g} s (a rate of {lo:g}-{hi:g} Hz)",
        ),
        pa.Check(
            lambda df: _mocap_intervals_constant(df["t"].to_numpy()),
            name=MOCAP_RATE_RULE,
            error=f"sample intervals not constant: one is not a whole number of the median interval "
            f"(+-{MOCAP_RATE_TOL:.0%} of it)",
        ),
    ]


def _from_base(df: pd.DataFrame, b: str) -> np.ndarray:
    """Per row: the distance of body b from the base where both are valid, else 0."""
    both = (df[f"{b}_valid"] & df["base_valid"]).to_numpy(bool)
    d = np.linalg.norm(
        df[[f"{b}_{f}" for f in "xyz"]].to_numpy(np.float64) - df[["base_x", "base_y", "base_z"]].to_numpy(np.float64),
        axis=1,
    )
    return np.where(both, d, 0.0)


def _from_base_check(b: str):
    import pandera.pandas as pa

    return pa.Check(
        lambda df: pd.Series(_from_base(df, b) <= MAX_FROM_BASE_M, index=df.index),
        name=FROM_BASE_RULE,
        error=f"{b} farther than {MAX_FROM_BASE_M:g} m from the base (positions not in metres?)",
    )


def _body_checks(b: str) -> list:
    import pandera.pandas as pa

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


@cache
def mocap_schema():
    import pandera.pandas as pa

    cols = {"t": pa.Column("float64", _increasing())}
    for b in BODIES:
        for f in POSE_FIELDS:
            # NaN allowed: tracking lost. Quaternions are checked as a whole (unit norm) below.
            cols[f"{b}_{f}"] = pa.Column("float64", nullable=True)
        cols[f"{b}_valid"] = pa.Column("bool")
    checks = _mocap_rate_checks()
    for b in BODIES:
        checks += _body_checks(b)
    checks += [_from_base_check(b) for b in BODIES if b != "base"]  # on complete poses: after the above
    assert list(cols) == mocap_columns()
    return pa.DataFrameSchema(cols, checks=checks, strict=True)


@cache
def servo_schema():
    import pandera.pandas as pa

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
    cols = {"t": pa.Column("float64", _increasing())}
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


def _iso8601(s: pd.Series) -> pd.Series:
    return pd.to_datetime(s, errors="coerce", format="ISO8601").notna()


def _known_category_check():
    import pandera.pandas as pa

    return pa.Check(_known_category, name="known category", error="category not one of its evidence set's")


def _nonempty():
    import pandera.pandas as pa

    return pa.Check.str_length(min_value=1, name="non-empty")


@cache
def meta_schema():
    """meta.json is validated as a one-row frame; keys beyond META_KEYS depend on the program."""
    import pandera.pandas as pa

    return pa.DataFrameSchema(
        {
            "group_id": pa.Column(str, _nonempty()),
            "evidence_set": pa.Column(str, _known_set()),
            "category": pa.Column(str),
            "session": pa.Column(str, _nonempty()),
        },
        checks=[_known_category_check()],
    )


@cache
def index_schema(pattern: str = GROUP_ID_PATTERN):
    """index.csv; `pattern` is what a group id may look like (config raw_data.group_id_pattern)."""
    import pandera.pandas as pa

    schema = pa.DataFrameSchema(
        {
            "group_id": pa.Column(
                str,
                pa.Check.str_matches(pattern, name="group id pattern", error=f"does not match {pattern}"),
                unique=True,
            ),
            "evidence_set": pa.Column(str, _known_set()),
            "category": pa.Column(str),
            "session": pa.Column(str, _nonempty()),
            "recorded_at": pa.Column(
                str, pa.Check(_iso8601, name="recorded_at is ISO 8601", error="not an ISO 8601 time")
            ),
            "n_mocap": pa.Column("int64", pa.Check.ge(0, name="row count >= 0"), coerce=True),
            "n_servo": pa.Column("int64", pa.Check.ge(0, name="row count >= 0"), coerce=True),
        },
        checks=[_known_category_check()],
        strict=True,
        ordered=True,
    )
    assert list(schema.columns) == list(INDEX_COLUMNS)
    return schema


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


def run_schema(schema, df, path, group, noun="column"):
    """Validate; on failure raise a RecordingError for the first broken rule.

    `group` is the group id, or a callable row-index -> group id (index.csv, one group a row).
    """
    import pandera.pandas as pa
    from pandera.errors import SchemaError, SchemaErrorReason, SchemaErrors

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


def _sorted_finite_t(t: np.ndarray, hz: float, tol: float) -> bool:
    if t.dtype != np.float64 or len(t) < 2 or not np.isfinite(t).all():
        return False
    dt = np.diff(t)
    return bool((dt > 0).all() and abs(np.median(dt) * hz - 1.0) <= tol)


_MOCAP_DTYPES = [np.dtype(bool) if c.endswith("_valid") else np.dtype(np.float64) for c in mocap_columns()]
_SERVO_TICKS = np.array([not c.startswith("current_") for c in servo_columns()[1:]])
# The fast path passes quaternions a hair inside the schema's tolerance: a norm at the very edge
# is left to pandera, so float round-off in a differently computed norm cannot flip a verdict.
_QUAT_FAST_TOL = QUAT_NORM_TOL * (1 - 1e-9)


def _mocap_passes(df: pd.DataFrame) -> bool:
    """Everything mocap_schema checks, in a few numpy passes over all bodies at once; True only
    when the schema passes. pandera then runs only on a frame this doubts, to name the first
    broken rule: a good recording is checked many times faster."""
    if list(df.columns) != mocap_columns() or list(df.dtypes) != _MOCAP_DTYPES:
        return False
    a = df.to_numpy(dtype=np.float64)  # one pass; flags become exactly 0.0 and 1.0
    t = a[:, 0]
    if not (np.isfinite(t).all() and _mocap_rate_in_range(t) and _mocap_intervals_constant(t)):
        return False
    body = a[:, 1:].reshape(len(a), len(BODIES), len(POSE_FIELDS) + 1)  # pose fields, then valid
    valid = body[:, :, -1] == 1.0
    pv = body[valid][:, :-1]  # every valid (sample, body): complete, unit quaternion
    q = pv[:, 3:]
    if not (np.isfinite(pv).all() and (np.abs(np.sqrt((q * q).sum(axis=1)) - 1) <= _QUAT_FAST_TOL).all()):
        return False
    base = BODIES.index("base")
    both = valid & valid[:, base : base + 1]  # complete poses, as just checked
    d = np.linalg.norm(body[:, :, :3] - body[:, base : base + 1, :3], axis=2)
    return bool((d[both] <= MAX_FROM_BASE_M).all())


def _servo_passes(df: pd.DataFrame) -> bool:
    """Everything servo_schema checks (see _mocap_passes)."""
    dtypes = list(df.dtypes)
    if list(df.columns) != servo_columns() or dtypes[0] != np.float64:
        return False
    for ticks, d in zip(_SERVO_TICKS, dtypes[1:]):
        if not isinstance(d, np.dtype) or d.kind not in ("iu" if ticks else "iuf"):
            return False
    a = df.to_numpy(dtype=np.float64)  # t is float64 already: its values are unchanged
    if not _sorted_finite_t(a[:, 0], SERVO_HZ, SERVO_RATE_TOL):
        return False
    # Ticks are integers far below 2**53, so as floats they compare exactly; currents must be
    # finite (the schema allows no NaN) and in range.
    a = np.abs(a[:, 1:])
    if not np.isfinite(a).all():
        return False
    return bool(a[:, _SERVO_TICKS].max() <= TICK_LIMIT and a[:, ~_SERVO_TICKS].max() <= CURRENT_LIMIT_MA)


# A row count as index_schema coerces it without doubt: plain digits, far below int64's limit.
_COUNT = r"[0-9]{1,15}"
_COUNTS = ("n_mocap", "n_servo")


def _index_passes(df: pd.DataFrame, pattern: str) -> bool:
    """Everything index_schema checks, with the same pandas calls as its checks but without
    pandera's overhead per check (see _mocap_passes)."""
    if list(df.columns) != list(INDEX_COLUMNS) or df.isna().to_numpy().any():
        return False
    if not all(pd.api.types.is_string_dtype(df[c]) for c in df):
        return False
    gid = df["group_id"]
    return bool(
        gid.str.match(pattern, na=False).all()
        and gid.is_unique
        and df["evidence_set"].isin(EVIDENCE_SETS).all()
        and (df["session"].str.len() >= 1).all()
        and _iso8601(df["recorded_at"]).all()
        and all(df[c].str.fullmatch(_COUNT).all() for c in _COUNTS)
        and _known_category(df).all()
    )


def _samples(df: pd.DataFrame, path, gid: str) -> None:
    # a rate needs an interval: before the schema, whose rate rule would say "median interval"
    if len(df) < 2:
        what = "empty: no rows" if len(df) == 0 else "one row: no interval between samples"
        raise RecordingError(path, gid, what, "a log holds at least 2 samples")


def check_mocap(df: pd.DataFrame, path, gid: str) -> None:
    _samples(df, path, gid)
    if not _mocap_passes(df):
        run_schema(mocap_schema(), df, path, gid)


def check_servo(df: pd.DataFrame, path, gid: str) -> None:
    _samples(df, path, gid)
    if not _servo_passes(df):
        run_schema(servo_schema(), df, path, gid)


def check_index(df: pd.DataFrame, path, pattern: str, group) -> pd.DataFrame:
    """index.csv's table (all strings) checked, its row counts as int64 (as the schema coerces
    them); `group`: row index -> group id, for the error line."""
    if _index_passes(df, pattern):
        return df.astype(dict.fromkeys(_COUNTS, "int64"))
    return run_schema(index_schema(pattern), df, path, group)


# --- readers that turn read failures into RecordingErrors ------------------------------------


def as_float64(df: pd.DataFrame) -> pd.DataFrame:
    """float32 columns (as many exporters write them) as the format's float64: exact, every
    float32 is a float64, so the rules judge the values recorded. The gate and the fits' loader
    (characterize/load.py) read through this; resampling's arithmetic on them is exact as it is."""
    narrow = {c: np.float64 for c, d in df.dtypes.items() if d == np.float32}
    return df.astype(narrow) if narrow else df


def read_recording(path: Path, gid: str) -> pd.DataFrame:
    if not path.exists():
        raise RecordingError(path, gid, "missing", "group has its three files")
    try:
        return as_float64(read_parquet(path))
    except (OSError, ValueError, pa_arrow.ArrowException) as e:
        raise RecordingError(path, gid, f"cannot be read: {e}", "readable parquet") from None


def load_recording(path: Path, gid: str) -> tuple[pd.DataFrame, bytes]:
    """The recording and its bytes, read once: the manifest hashes the bytes that were checked."""
    if not path.exists():
        raise RecordingError(path, gid, "missing", "group has its three files")
    try:
        data = path.read_bytes()
        return as_float64(parquet_from_bytes(data)), data
    except Exception:  # noqa: BLE001 -- re-read below, so the error is read_recording's own line
        pass
    return read_recording(path, gid), path.read_bytes()


def recording_rows(path: Path, gid: str) -> int:
    try:
        return parquet_rows(path)  # footer only: fast on a thousand groups
    except (OSError, ValueError, pa_arrow.ArrowException) as e:
        raise RecordingError(path, gid, f"cannot be read: {e}", "readable parquet") from None


def _meta_passes(meta: dict) -> bool:
    """Everything meta_schema checks, in plain Python (see _mocap_passes). ASCII only: other
    text goes through pandera's frame, as it always did."""
    v = [meta.get(k) for k in META_KEYS]
    if not all(type(x) is str and x.isascii() for x in v):
        return False
    gid, es, cat, session = v
    return gid != "" and session != "" and es in EVIDENCE_SETS and cat in CATEGORIES.get(es, ())


def read_meta_checked(path: Path, gid: str, index_row: dict | None = None) -> dict:
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
    if not _meta_passes(meta):
        run_schema(
            meta_schema(), pd.DataFrame([{k: meta[k] for k in META_KEYS if k in meta}]), path, gid, noun="key"
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


def file_entry(path: Path, data: bytes | None = None) -> dict:
    """Path, sha256 and size; `data` is the file's bytes when the caller has read them already."""
    data = path.read_bytes() if data is None else data
    return {"path": str(path), "sha256": hashlib.sha256(data).hexdigest(), "bytes": len(data)}


