"""OptiTrack Motive CSV exports (format versions 1.21-1.25) as plain tables.

A Motive CSV is one metadata row (key, value pairs), a blank row, the tagged header rows (Type,
Name, ID and from 1.25 Parent, each tag in the first or second cell), a component row (Rotation,
Position, Mean Marker Error, Marker Quality), an axis row that starts with Frame, then one row per
frame. A blank cell is an occluded value. Positions come back in metres and quaternions as
qw, qx, qy, qz (Motive writes X, Y, Z, W), with their sign as exported: q and -q are the same
rotation, and Motive flips between them from one frame to the next.

Time is Frame / Export Frame Rate. Motive writes the Time column from the same two, to the
microsecond, and NMotive rounds it to the millisecond (0.003, 0.006, 0.008, ... at 360 Hz): that
column is not a clock, only a check. A Time more than half a millisecond from Frame / rate is
refused (a wrong rate in the header, or a column edited), so the rounding passes and nothing else.

Refused (CaptureError): no Format Version, a version outside 1.21-1.25, a rotation type other
than Quaternion, missing or unknown length units, a Coordinate Space other than Global, a name
given twice within one column type, frames out of order or repeated, a Time column that
disagrees with Frame / rate, a column type this reader does not know, and a truncated file.
Coordinate Space Local puts each bone relative to its parent bone, not in the capture volume:
the lab frame is the capture's, so such a take is refused (export it with world coordinates).
Truncated means a data row with fewer cells than the axis row, or a file whose last row does not
end with a line break (Motive ends every row with one): what a copy cut short leaves. A file cut
at a row boundary reads as a shorter take; `total_frames` (the header's Total Exported Frames)
lets the caller compare, since an excerpt of a take is a legitimate edit. The frame rate itself
is not judged here.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import CaptureError

VERSIONS = ("1.21", "1.22", "1.23", "1.24", "1.25")
TO_METRES = {"Millimeters": 1e-3, "Centimeters": 1e-2, "Meters": 1.0}
TAGS = ("Type", "Name", "ID", "Parent")
POSE_COLUMNS = ["x", "y", "z", "qw", "qx", "qy", "qz"]
POINT_COLUMNS = ["x", "y", "z"]
# (component, axis) -> our column; the single-column extras (Mean Marker Error, Marker Quality)
# are quality figures of Motive's solver, not data, and are left out.
FIELDS = {("Position", a): a.lower() for a in "XYZ"} | {("Rotation", a): "q" + a.lower() for a in "WXYZ"}
# column type -> (Take field, columns): Rigid Body Markers and Bone Markers are where Motive's
# solver puts a body's markers, and Motive names them like the measured Markers ("Body:Marker1"),
# so they get their own table rather than sharing one with the Markers.
KINDS = {
    "Rigid Body": ("rigid_bodies", POSE_COLUMNS),
    "Bone": ("bones", POSE_COLUMNS),
    "Marker": ("markers", POINT_COLUMNS),
    "Unlabeled Marker": ("markers", POINT_COLUMNS),
    "Rigid Body Marker": ("body_markers", POINT_COLUMNS),
    "Bone Marker": ("body_markers", POINT_COLUMNS),
}
HEADER_SEARCH = 20  # the axis row is within the first few lines of every version
# NMotive rounds Time to 1 ms: at most half of it from Frame / rate, plus float round-off
TIME_TOL_S = 0.5e-3
SPACES = ("Global",)  # Coordinate Space: Local is relative to each bone's parent (the docstring)


@dataclass(frozen=True, eq=False)
class Take:
    path: Path
    name: str
    version: str
    rate_hz: float  # Export Frame Rate
    units: str  # as the file names them; the tables are in metres whatever they are
    rotation: str
    space: str  # Coordinate Space: Global (SPACES)
    start_time: str  # Capture Start Time as written: its format follows the exporting PC's locale
    total_frames: int | None  # Total Exported Frames as the header declares it
    t: np.ndarray  # seconds, Frame / Export Frame Rate (the Time column agrees to TIME_TOL_S)
    frame: np.ndarray  # ints
    timecode: np.ndarray | None  # strings, when the export has a TimeCode column
    rigid_bodies: dict[str, pd.DataFrame]  # x, y, z (m), qw, qx, qy, qz, valid
    bones: dict[str, pd.DataFrame]  # as rigid_bodies
    markers: dict[str, pd.DataFrame]  # Marker and Unlabeled Marker: x, y, z (m), valid
    body_markers: dict[str, pd.DataFrame]  # Rigid Body Marker and Bone Marker: as markers


def read_motive_csv(path: str | Path) -> Take:
    path = Path(path)
    # one read, universal newlines: CRLF and LF exports parse the same; a locale's start time in
    # a non-UTF-8 code page must not stop the read, so undecodable bytes become U+FFFD
    text = path.read_text(encoding="utf-8-sig", errors="replace")
    lines = text.split("\n")
    meta = _metadata(path, lines[0])
    first, axis, levels = _header(path, lines)
    _check_cells(path, text, lines, axis)
    try:
        df = pd.read_csv(io.StringIO(text), skiprows=first, header=list(range(axis - first + 1)))
    except (pd.errors.ParserError, ValueError) as e:
        raise CaptureError(
            path,
            f"not readable as a Motive table ({str(e).splitlines()[0]})",
            "a Motive CSV export",
        ) from None
    cols = [dict(zip(levels, (_blank_unnamed(v) for v in c))) for c in df.columns]
    frame, t = _frames(path, df, cols, meta["rate_hz"])
    scale = TO_METRES[meta["units"]]
    tables = _tables(path, df, cols, scale)
    tc = [i for i, c in enumerate(cols) if c["axis"] == "TimeCode"]
    return Take(
        path=path,
        frame=frame,
        t=t,
        timecode=df.iloc[:, tc[0]].astype(str).to_numpy() if tc else None,
        **meta,
        **{field: tables.get(field, {}) for field in ("rigid_bodies", "bones", "markers", "body_markers")},
    )


def _metadata(path, line):
    row = next(csv.reader([line]), [])
    if not row or row[0] != "Format Version":
        raise CaptureError(
            path,
            "its first cell is not 'Format Version'",
            "a Motive export opens with its metadata row",
        )
    meta = {k.strip(): v.strip() for k, v in zip(row[0::2], row[1::2])}
    if meta["Format Version"] not in VERSIONS:
        raise CaptureError(path, f"format version {meta['Format Version']!r}", "Motive format version 1.21-1.25")
    if meta.get("Rotation Type") != "Quaternion":
        raise CaptureError(path, f"rotation type {meta.get('Rotation Type')!r}", "rotation type Quaternion")
    units = meta.get("Length Units")
    if units is None:
        raise CaptureError(path, "no Length Units in the metadata row", "length units given")
    if units not in TO_METRES:
        raise CaptureError(path, f"length units {units!r}", "length units Millimeters, Centimeters or Meters")
    try:
        rate = float(meta["Export Frame Rate"])
    except (KeyError, ValueError):
        rate = float("nan")
    if not rate > 0:
        raise CaptureError(path, "no positive Export Frame Rate in the metadata row", "a capture rate in the file")
    space = meta.get("Coordinate Space", "")
    if space not in SPACES:
        what = f"Coordinate Space {space!r}" if space else "no Coordinate Space in the metadata row"
        if space == "Local":
            what += ": a Local take puts each bone relative to its parent, not in the capture volume"
        raise CaptureError(path, what, "Coordinate Space Global (export with world coordinates)")
    total = meta.get("Total Exported Frames", "")
    return dict(
        name=meta.get("Take Name", ""),
        version=meta["Format Version"],
        rate_hz=rate,
        units=units,
        rotation=meta["Rotation Type"],
        space=space,
        start_time=meta.get("Capture Start Time", ""),
        total_frames=int(total) if total.isdigit() else None,
    )


def _header(path, lines):
    """Line numbers of the first tagged row and of the axis row, and the header's level names."""
    rows = list(csv.reader(lines[:HEADER_SEARCH]))
    axis = next((i for i, r in enumerate(rows) if r and r[0] == "Frame"), None)
    if axis is None:
        raise CaptureError(
            path,
            "no axis row starting with 'Frame' in the header",
            "a Motive header ends with its Frame row",
        )
    tags = {}
    for i, r in enumerate(rows[1:axis], 1):
        tag = next((c for c in r[:2] if c), "")
        if tag in TAGS:
            tags[i] = tag
    missing = [t for t in ("Type", "Name", "ID") if t not in tags.values()]
    if missing:
        raise CaptureError(
            path,
            f"no {', '.join(missing)} row in the header",
            "a Motive header has Type, Name and ID rows",
        )
    first = min(tags)
    # the tagged rows, then the component row, then the axis row, with nothing between
    if sorted(tags) != list(range(first, axis - 1)):
        raise CaptureError(
            path,
            "the Type, Name, ID rows are not followed by a component row and the Frame row",
            "a Motive header's rows in order",
        )
    return first, axis, [tags[i] for i in sorted(tags)] + ["component", "axis"]


def _check_cells(path, text, lines, axis):
    if not text.endswith("\n"):
        raise CaptureError(path, "truncated: the last row does not end with a line break", "a complete file")
    width = lines[axis].count(",") + 1
    data = lines[axis + 1 :]
    while data and not data[-1]:  # the empty string after the final line break, and blank lines at the end
        data.pop()
    # Motive quotes only header cells, so a data row's commas are its cell boundaries
    short = next((i for i, ln in enumerate(data) if ln.count(",") + 1 < width), None)
    if short is not None:
        n = data[short].count(",") + 1
        raise CaptureError(
            path,
            f"truncated: line {axis + 2 + short} has {n} of the header's {width} cells",
            "a complete file",
        )


def _blank_unnamed(v):
    # pandas names a blank header cell "Unnamed: <i>_level_<j>"
    return "" if v.startswith("Unnamed: ") else v


def _frames(path, df, cols, rate):
    def column(name):
        i = next((i for i, c in enumerate(cols) if c["axis"] == name), None)
        if i is None:
            raise CaptureError(path, f"no {name!r} column", "a Motive table has Frame and Time (Seconds) columns")
        values = pd.to_numeric(df.iloc[:, i], errors="coerce").to_numpy(float)
        if np.isnan(values).any():
            raise CaptureError(
                path,
                f"a blank or non-numeric cell in the {name!r} column",
                "every frame numbered and timed",
            )
        return values

    frame, t = column("Frame"), column("Time (Seconds)")
    if (frame != np.round(frame)).any():
        raise CaptureError(path, "a Frame number that is not an integer", "every frame numbered and timed")
    frame = frame.astype(int)
    step = np.diff(frame)
    if (step == 0).any():
        raise CaptureError(path, f"frame {frame[1:][step == 0][0]} is duplicated", "frames in order, each once")
    if (step < 0).any():
        i = int(np.flatnonzero(step < 0)[0])
        raise CaptureError(
            path,
            f"frames out of order: frame {frame[i + 1]} after frame {frame[i]}",
            "frames in order, each once",
        )
    clock = frame / rate
    off = np.abs(t - clock)
    if (off > TIME_TOL_S + 1e-9).any():
        i = int(np.flatnonzero(off > TIME_TOL_S + 1e-9)[0])
        raise CaptureError(
            path,
            f"frame {frame[i]}: the Time column says {t[i]:.6f} s, Frame / Export Frame Rate "
            f"{clock[i]:.6f} s ({off[i] * 1e3:.3f} ms apart)",
            f"Time is Frame / Export Frame Rate to within {TIME_TOL_S * 1e3:g} ms",
        )
    return frame, clock


def _tables(path, df, cols, scale):
    """{Take field: {name: DataFrame}} from the data columns, grouped by type and name."""
    groups: dict[tuple[str, str], dict[str, int]] = {}
    for i, c in enumerate(cols):
        if c["axis"] in ("Frame", "Time (Seconds)", "TimeCode"):
            continue
        if c["Type"] not in KINDS:
            raise CaptureError(path, f"column type {c['Type']!r}", f"column types {', '.join(KINDS)}")
        field = FIELDS.get((c["component"], c["axis"]))
        if field is None:
            continue
        fields = groups.setdefault((c["Type"], c["Name"]), {})
        if field in fields:
            raise CaptureError(
                path,
                f"{c['Type']} {c['Name']!r} appears twice (a second {c['component']} {c['axis']})",
                "each body or marker named once",
            )
        fields[field] = i
    tables: dict[str, dict[str, pd.DataFrame]] = {}
    for (kind, name), fields in groups.items():
        field, columns = KINDS[kind]
        missing = [c for c in columns if c not in fields]
        if missing:
            raise CaptureError(
                path,
                f"{kind} {name!r} has no {', '.join(missing)} column",
                "every component of a body or marker",
            )
        table = tables.setdefault(field, {})
        if name in table:  # a Marker and an Unlabeled Marker of one name
            raise CaptureError(path, f"marker {name!r} appears twice", "each body or marker named once")
        table[name] = _table(path, df, fields, columns, scale)
    return tables


def _table(path, df, fields, columns, scale):
    try:
        out = pd.DataFrame({c: df.iloc[:, fields[c]].to_numpy(float) for c in columns})
    except ValueError:
        raise CaptureError(
            path,
            f"a non-numeric cell among columns {sorted(fields.values())}",
            "cells are numbers or blank",
        ) from None
    out[POINT_COLUMNS] *= scale  # positions only: quaternions have no unit
    out["valid"] = out[columns].notna().all(axis=1)
    return out
