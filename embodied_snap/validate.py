"""The gate: every rule a recording must satisfy, checked in one place (docs/data.md lists them
with their config keys).

`esnap validate`, the workflow's plan (rules/common.smk, before any job reads a shard) and its
validation jobs all call these functions, so they cannot disagree. The table rules are the
schemas of rawschema.py; here are the rules that span files or need limits from config: time
base, holes and dropouts in both logs, tracked-body coverage, physically impossible motion,
labels and program per evidence set, format version, one recording in one group. The first
broken rule raises a RecordingError, one line naming the file, the group and the rule. Nothing
downstream decides again whether a group is usable.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .protocol import params
from .rawformat import (
    FORMAT_VERSION,
    GOAL_TIMING,
    GROUP_FILES,
    RecordingError,
    goal_timing,
    group_paths,
    raw_file,
)
from .rawschema import (
    COVER_TOL_S,
    GROUP_ID_PATTERN,
    TRACKED_BODIES,
    check_index,
    check_mocap,
    check_servo,
    file_entry,
    load_recording,
    read_meta_checked,
    recording_rows,
)

__all__ = [
    "Limits",
    "RecordingError",
    "TRACKED_BODIES",
    "read_index",
    "check_folders",
    "check_one_recording",
    "validate_group",
    "validate_index",
    "validate_shard",
]

# Manifest names and group_paths' keys, in the manifest's order.
_FILE_KEYS = [(name, name.split(".")[0]) for name in GROUP_FILES]
# What a group recorded, as opposed to meta.json, which describes it (and names its group).
RECORDINGS = tuple(name for name in GROUP_FILES if name.endswith(".parquet"))
ONE_RECORDING_RULE = "one recording, one group"


@dataclass(frozen=True)
class Limits:
    """The gate's limits. They have no defaults: config.yaml holds them (its `gate:` section, the
    sampling section of the protocol and raw_data.group_id_pattern); `from_config` builds them."""

    max_mocap_gap_s: float  # resample.max_gap_s: what passes is what resampling bridges
    hz: float  # protocol.GRID_HZ: dropouts count on the span of the grid resampling fills
    max_servo_gap_s: float
    max_speed_mps: dict
    min_target_valid_fraction: float
    target_groups: tuple
    labels: dict
    program: dict
    group_id_pattern: str

    @classmethod
    def from_config(cls, config: dict) -> "Limits":
        """The limits of a (validated) config; the sampling values come through the protocol."""
        g = config["gate"]
        s = params(config, "sampling")["sampling"]
        return cls(
            max_mocap_gap_s=s["max_gap_s"],
            hz=float(s["hz"]),
            max_servo_gap_s=g["max_servo_gap_s"],
            max_speed_mps=g["max_speed_mps"],
            min_target_valid_fraction=g["min_target_valid_fraction"],
            target_groups=tuple(g["target_groups"]),
            labels=g["labels"],
            program=g["program"],
            group_id_pattern=config["raw_data"]["group_id_pattern"],
        )

    def of(self, table: dict, es: str, cat: str):
        """A per-evidence-set entry: `<set>/<category>` overrides `<set>`."""
        return table.get(f"{es}/{cat}", table.get(es))


# --- rules that need limits --------------------------------------------------------------------


def _check_meta(meta: dict, path, gid: str, lim: Limits, t_span) -> None:
    v = meta.get("format_version", FORMAT_VERSION)  # recordings that predate the key are version 1
    if type(v) is not int or v != FORMAT_VERSION:
        raise RecordingError(
            path,
            gid,
            f"format_version {v!r}; this pipeline reads {FORMAT_VERSION}",
            f"format version {FORMAT_VERSION}",
        )
    if goal_timing(meta) not in GOAL_TIMING:
        raise RecordingError(
            path,
            gid,
            f"goal_timing {meta['goal_timing']!r}",
            f"goal_timing one of {', '.join(GOAL_TIMING)}",
        )
    es, cat = meta["evidence_set"], meta["category"]
    for key, table in (("program", lim.program), ("labels", lim.labels)):
        need = lim.of(table, es, cat)
        if need is None:
            raise RecordingError(
                path, gid, f"no gate.{key} entry for {es}", f"gate.{key} names every evidence set"
            )
        got = meta.get(key)
        if not isinstance(got, dict):
            raise RecordingError(
                path, gid, f"'{key}' missing or not an object", f"{key} complete per evidence set"
            )
        for k in need:
            if got.get(k) is None:
                raise RecordingError(
                    path,
                    gid,
                    f"{key} has no '{k}' ({es}/{cat} needs {', '.join(need)})",
                    f"{key} complete per evidence set",
                )
    for k, val in meta["labels"].items():
        # Times are when things happened in this recording: numbers inside its time span.
        if k.startswith("t_") and val is not None:
            if (
                isinstance(val, bool)
                or not isinstance(val, (int, float))
                or not t_span[0] <= val <= t_span[1]
            ):
                raise RecordingError(
                    path,
                    gid,
                    f"label {k}={val!r} is not a time in {t_span[0]:.3f}..{t_span[1]:.3f} s",
                    "label times inside the recording",
                )
        elif k in ("attached", "retrieved", "snap_speed_event") and not isinstance(val, bool):
            raise RecordingError(
                path, gid, f"label {k}={val!r} is not true/false", "outcome labels are booleans"
            )


def _longest(t: np.ndarray, ok: np.ndarray, t0: float, t1: float):
    """Longest span of [t0, t1] without a sample where `ok`: (length, start, end)."""
    pts = np.concatenate([[t0], t[ok], [t1]])
    k = int(np.argmax(np.diff(pts)))
    return pts[k + 1] - pts[k], pts[k], pts[k + 1]


def _grid_span(tm: np.ndarray, ts: np.ndarray, hz: float):
    """First and last point of the 50 Hz grid resampling fills (resample.resample_group)."""
    t0, t1 = max(tm[0], ts[0]), min(tm[-1], ts[-1])
    return np.ceil(t0 * hz - 1e-6) / hz, np.floor(t1 * hz + 1e-6) / hz


def _columns(mocap: pd.DataFrame) -> dict:
    """A checked mocap table as numpy columns, in one conversion (pandas' per-column access costs
    more than the checks). The schema made t and poses float64 and flags bool, so float64 holds
    every value exactly; a flag is 1.0 or 0.0."""
    if not mocap.columns.is_unique:
        return {c: mocap[c].to_numpy() for c in mocap.columns}
    a = mocap.to_numpy(dtype=np.float64)
    return {c: (a[:, i] == 1.0 if c.endswith("_valid") else a[:, i]) for i, c in enumerate(mocap.columns)}


def _check_motion(mocap: dict, path, gid: str, lim: Limits, has_target: bool, span) -> None:
    t = mocap["t"]
    gap = float(np.diff(t).max())
    if gap > lim.max_mocap_gap_s + 1e-9:  # rows missing altogether: every body lost at once
        k = int(np.argmax(np.diff(t)))
        raise RecordingError(
            path,
            gid,
            f"no sample for {gap:.3f} s from t={t[k]:.3f} to t={t[k + 1]:.3f} s",
            f"mocap hole <= {lim.max_mocap_gap_s:g} s",
        )
    bodies = TRACKED_BODIES + (("target",) if has_target else ())
    for b in bodies:
        ok = mocap[f"{b}_valid"]
        if b == "target":
            frac = float(ok.mean())
            if frac < lim.min_target_valid_fraction:
                raise RecordingError(
                    path,
                    gid,
                    f"target tracked in {frac:.0%} of samples",
                    f"target tracked >= {lim.min_target_valid_fraction:.0%}",
                )
        elif not ok.any():
            raise RecordingError(
                path, gid, f"{b} never tracked", f"mocap dropout <= {lim.max_mocap_gap_s:g} s"
            )
        else:
            # Exactly resampling's bridging rule: gaps on the grid's span, its edges included.
            n, a, e = _longest(np.clip(t, *span), ok, *span)
            if n > lim.max_mocap_gap_s + 1e-9:
                raise RecordingError(
                    path,
                    gid,
                    f"{b} not tracked for {n:.3f} s from t={a:.3f} to t={e:.3f} s",
                    f"mocap dropout <= {lim.max_mocap_gap_s:g} s",
                )
        vmax = lim.max_speed_mps.get(b)
        if vmax is None or ok.sum() < 2:
            continue
        p = np.column_stack([mocap[f"{b}_{c}"][ok] for c in "xyz"])
        tv = t[ok]
        d = np.linalg.norm(np.diff(p, axis=0), axis=1)
        v = d / np.diff(tv)
        k = int(np.argmax(v))
        if v[k] > vmax:
            raise RecordingError(
                path,
                gid,
                f"{b} moves {d[k]:.3f} m in {tv[k + 1] - tv[k]:.4f} s ({v[k]:.1f} m/s) "
                f"at t={tv[k]:.3f} s",
                f"{b} speed <= {vmax:g} m/s",
            )


def _check_servo(servo: pd.DataFrame, mocap: pd.DataFrame, path, gid: str, lim: Limits) -> None:
    # Every 50 Hz state needs servo positions, so the servo log must span the mocap, densely.
    tm, ts = mocap["t"].to_numpy(), servo["t"].to_numpy()
    if ts[0] > tm[0] + COVER_TOL_S or ts[-1] < tm[-1] - COVER_TOL_S:
        raise RecordingError(
            path,
            gid,
            f"servo log spans {ts[0]:.3f}..{ts[-1]:.3f} s, mocap {tm[0]:.3f}..{tm[-1]:.3f} s",
            "servo log covers mocap",
        )
    check_servo_gaps(ts, path, gid, lim.max_servo_gap_s)


def check_servo_gaps(ts: np.ndarray, path, gid: str, max_gap_s: float) -> None:
    """No interval between sync-reads longer than max_gap_s (config gate.max_servo_gap_s); also
    what `esnap lab acquire` asks of a log as soon as it is recorded."""
    dt = np.diff(ts)
    k = int(np.argmax(dt))
    if dt[k] > max_gap_s + 1e-9:
        raise RecordingError(
            path,
            gid,
            f"no sync-read for {dt[k]:.3f} s from t={ts[k]:.3f} to t={ts[k + 1]:.3f} s",
            f"servo log gap <= {max_gap_s:g} s",
        )


# --- public API ------------------------------------------------------------------------------


def validate_group(raw_dir, group_id: str, index_row: dict | None = None, *, limits: Limits) -> dict:
    """Every rule for one group, under the config's limits (Limits.from_config); return its
    raw-manifest entry (sha256 per file)."""
    lim = limits
    paths = group_paths(raw_dir, group_id)  # ids are names: the folder stays inside raw_dir
    meta = read_meta_checked(paths["meta"], group_id, index_row)
    # Each parquet file is read once: the checked bytes are the hashed bytes.
    mocap, mocap_bytes = load_recording(paths["mocap"], group_id)
    check_mocap(mocap, paths["mocap"], group_id)
    servo, servo_bytes = load_recording(paths["servo"], group_id)
    check_servo(servo, paths["servo"], group_id)
    tm = mocap["t"].to_numpy()
    _check_meta(meta, paths["meta"], group_id, lim, (tm[0], tm[-1]))
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
    es, cat = meta["evidence_set"], meta["category"]
    has_target = es in lim.target_groups or f"{es}/{cat}" in lim.target_groups
    if has_target and not isinstance(meta.get("target"), dict):
        raise RecordingError(
            paths["meta"],
            group_id,
            f"no 'target' object in a {es}/{cat} group",
            "target trials describe the target",
        )
    _check_servo(servo, mocap, paths["servo"], group_id, lim)
    cols = _columns(mocap)
    _check_motion(
        cols, paths["mocap"], group_id, lim, has_target, _grid_span(tm, servo["t"].to_numpy(), lim.hz)
    )
    valid = np.logical_and.reduce([cols[f"{b}_valid"] for b in TRACKED_BODIES])
    data = {"mocap": mocap_bytes, "servo": servo_bytes}
    return {
        "group_id": group_id,
        "evidence_set": es,
        "category": cat,
        "session": meta["session"],
        "files": {name: file_entry(paths[k], data.get(k)) for name, k in _FILE_KEYS},
        "n_mocap": int(len(mocap)),
        "n_servo": int(len(servo)),
        "duration_s": float(tm[-1] - tm[0]),
        "mocap_valid_fraction": float(valid.mean()),
    }


def read_index(raw_dir, pattern: str = GROUP_ID_PATTERN) -> pd.DataFrame:
    """index.csv as a table of strings (counts as int), or a one-line RecordingError: missing,
    empty, unreadable, wrong columns, bad or duplicate ids, unknown sets or categories."""
    path = raw_file(raw_dir, "index.csv")  # a link out is refused before it is opened
    if not path.is_file():
        raise RecordingError(path, "-", "missing", "raw_data/index.csv lists every group")
    try:
        # csv first: pandas' own errors on odd files are tracebacks, not rules.
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise RecordingError(path, "-", f"cannot be read: {e}", "readable csv") from None
    if not rows:
        raise RecordingError(path, "-", "empty file", "index.csv has a header and a row per group")
    header, body = rows[0], rows[1:]
    if any(len(r) != len(header) for r in body):
        n = next(i for i, r in enumerate(body) if len(r) != len(header))
        raise RecordingError(
            path,
            body[n][0] if body[n] else "-",
            f"row {n + 1} has {len(body[n])} fields, header {len(header)}",
            "readable csv",
        )
    raw = pd.DataFrame(body, columns=header, dtype=str)
    if raw.columns.duplicated().any():
        raise RecordingError(path, "-", f"repeated column in {header}", "index columns")
    gid_of = lambda row: raw["group_id"].iloc[int(row)] if "group_id" in raw else "-"  # noqa: E731
    return check_index(raw, path, pattern, gid_of)


def check_folders(raw_dir, group_ids) -> None:
    """Every folder under groups/ is a listed group (a stray folder is a group nobody planned)."""
    groups = Path(raw_dir) / "groups"
    listed = set(group_ids)
    if groups.is_dir():
        for p in sorted(groups.iterdir()):
            if not p.name.startswith(".") and p.is_dir() and p.name not in listed:
                raise RecordingError(
                    p, p.name, "folder has no row in index.csv", "every group has an index row"
                )


def validate_index(raw_dir, limits: Limits, open_files: bool = True) -> pd.DataFrame:
    """index.csv against the group folders (cheap: parquet footers and meta.json only). With
    open_files=False only the index and the folders' files are looked at (the workflow's index job:
    each group's row counts and meta.json are checked against its row by validate_group, in its
    shard's job, which declares those files)."""
    lim = limits
    path = Path(raw_dir) / "index.csv"
    index = read_index(raw_dir, lim.group_id_pattern)
    check_folders(raw_dir, index.group_id)
    for row in index.to_dict("records"):
        gid, paths = row["group_id"], group_paths(raw_dir, row["group_id"])
        for p in paths.values():
            if not p.exists():
                raise RecordingError(p, gid, "missing (listed in index.csv)", "index row has its files")
        if not open_files:
            continue
        for key, p in (("n_mocap", paths["mocap"]), ("n_servo", paths["servo"])):
            n = recording_rows(p, gid)
            if n != row[key]:
                raise RecordingError(
                    path, gid, f"{key} {row[key]} but {p.name} has {n} rows", f"{key} matches {p.name}"
                )
        read_meta_checked(paths["meta"], gid, row)
    return index


def check_one_recording(entries) -> None:
    """No recording in two groups: one file (a link inside the raw directory, a hard link) or one
    content (a copied take) counted under two labels would enter a fit twice. `entries` are
    manifest entries (validate_group's, a shard record's), in the gate's order; the later group of
    the first pair that shares a mocap or servo log's sha256 is refused, naming the earlier one."""
    held = {}
    for e in entries:
        for name in RECORDINGS:
            f = e["files"][name]
            gid, path = held.setdefault(f["sha256"], (e["group_id"], f["path"]))
            if gid != e["group_id"]:
                raise RecordingError(f["path"], e["group_id"], f"{_same(f['path'], path)} {path} of group {gid}",
                                     ONE_RECORDING_RULE)


def _same(a, b) -> str:
    try:
        return "the same file as" if os.path.samefile(a, b) else "the same bytes as"
    except OSError:
        return "the same bytes as"


def validate_shard(
    raw_dir, group_ids: list[str], index: pd.DataFrame, limits: Limits
) -> list[dict]:
    """Manifest entries of a shard's groups, each checked against its index.csv row."""
    rows = {r["group_id"]: r for r in index.to_dict("records")}
    out = []
    for gid in group_ids:
        if gid not in rows:
            raise RecordingError(
                Path(raw_dir) / "index.csv", gid, "no row in index.csv", "every group has an index row"
            )
        out.append(validate_group(raw_dir, gid, rows[gid], limits=limits))
    return out
