"""C3D files (Vicon, Qualisys, Motive, ...) as plain marker tables, through ezc3d.

Only the 3D points are read: analog channels, force plates and events are left to their own
readers. ezc3d applies POINT:SCALE (a negative scale means float storage) and marks a point
whose residual is negative as NaN; both count as occluded here, as a negative residual does.

A file cut short is refused: ezc3d reads the frames that are there and rewrites the header's
count to match, so the count the file declares is read from its own header (words 4 and 5: the
first and last frame) and compared with the frames read. Past 65,535 frames that word saturates
and is a lower bound, still one a complete file reaches.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import ezc3d
import numpy as np
import pandas as pd

from .errors import CaptureError

TO_METRES = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}
# The parameter section's processor type (its 4th byte, 83 + type): MIPS writes big-endian words
BIG_ENDIAN = 86


@dataclass(frozen=True, eq=False)
class MarkerTake:
    path: Path
    rate_hz: float  # POINT:RATE
    first_frame: int  # as the file's header counts it, from 1
    units: str  # POINT:UNITS as written; the tables are in metres
    t: np.ndarray  # seconds since the first frame
    markers: dict[str, pd.DataFrame]  # label -> x, y, z (m), valid


def read_c3d(path: str | Path) -> MarkerTake:
    path = Path(path)
    try:
        c = ezc3d.c3d(str(path))
    except RuntimeError as e:
        raise CaptureError(path, f"not readable as C3D ({str(e).splitlines()[0]})", "a C3D file ezc3d reads") from None
    point = c["parameters"]["POINT"]
    labels = _labels(point)
    if not labels:
        raise CaptureError(path, "no point labels (POINT:LABELS is empty)", "markers are named by POINT:LABELS")
    if len(set(labels)) < len(labels):
        dup = next(lb for lb in labels if labels.count(lb) > 1)
        raise CaptureError(path, f"point label {dup!r} appears twice", "each marker named once")
    units = _value(point, "UNITS", "").strip()
    if units not in TO_METRES:
        raise CaptureError(path, f"POINT:UNITS {units!r}", "length units mm, cm or m")
    rate = float(_value(point, "RATE", 0.0))
    if not rate > 0:
        raise CaptureError(path, "no positive POINT:RATE", "a capture rate in the file")
    xyz = c["data"]["points"][:3] * TO_METRES[units]  # (3, points, frames)
    first, last = _declared_frames(path)
    if xyz.shape[2] < last - first + 1:
        raise CaptureError(
            path,
            f"truncated: its header declares {last - first + 1} frames ({first}-{last}), the file holds {xyz.shape[2]}",
            "a complete file",
        )
    residual = c["data"]["meta_points"]["residuals"][0]
    markers = {}
    for i, label in enumerate(labels):
        table = pd.DataFrame(xyz[:, i].T, columns=["x", "y", "z"])
        # ezc3d already gives such a point NaN; the residual keeps it occluded should it not
        table["valid"] = table.notna().all(axis=1).to_numpy() & ~(residual[i] < 0)
        markers[label] = table
    return MarkerTake(
        path=path,
        rate_hz=rate,
        first_frame=int(c["header"]["points"]["first_frame"]) + 1,  # ezc3d counts from 0
        units=units,
        t=np.arange(xyz.shape[2]) / rate,
        markers=markers,
    )


def _declared_frames(path):
    """(first, last) frame as the file's header declares them, before ezc3d corrects them."""
    with open(path, "rb") as f:
        head = f.read(512)
        f.seek((head[0] - 1) * 512 + 3)  # byte 1: the parameter section's first 512-byte block
        order = ">" if f.read(1) == bytes([BIG_ENDIAN]) else "<"
    return struct.unpack(order + "HH", head[6:10])


def _labels(point):
    # past 255 points the labels continue in LABELS2, LABELS3, ...; only the first USED are points
    labels, k = list(_value(point, "LABELS", [], all_=True)), 2
    while f"LABELS{k}" in point:
        labels += _value(point, f"LABELS{k}", [], all_=True)
        k += 1
    used = int(_value(point, "USED", len(labels)))
    return [lb.strip() for lb in labels[:used]]


def _value(group, name, default, all_=False):
    values = group.get(name, {}).get("value")
    if values is None or len(values) == 0:
        return default
    return list(values) if all_ else values[0]
