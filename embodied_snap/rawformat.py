"""The rig recording format, version 1 (docs/design.md section 2): the one place that names it.

Lab frame in metres, Y up. Servo positions in Dynamixel ticks (XM430-W350-R, 4096 ticks/rev).
Every writer (simulated rig, deployment recorder) and every reader (validation, resampling)
takes its column names from here.
"""

from __future__ import annotations

import functools
import json
import os
import tempfile
from pathlib import Path

import pandas as pd

FORMAT_VERSION = 1
MOCAP_HZ = 240.0
SERVO_HZ = 100.0
TICKS_PER_REV = 4096
N_SERVOS = 9

BODIES = ("base", "s1", "s2", "tip", "target")
POSE_FIELDS = ("x", "y", "z", "qw", "qx", "qy", "qz")
SERVO_IDS = tuple(range(1, N_SERVOS + 1))

EVIDENCE_SETS = (
    "servo_calibration",
    "attachment",
    "release_mode",
    "delay_sweep",
    "dynamics",
    "held_base",
    "deployment",
)
# Categories of each evidence set (paper Table I and section IV-A).
CATEGORIES = {
    "servo_calibration": ("burst",),
    "attachment": ("target",),
    "release_mode": ("direct", "ramped", "instantaneous"),
    "delay_sweep": ("sweep",),
    "dynamics": ("free_space", "target", "sealed", "pilot", "characterisation"),
    "held_base": ("held",),
    "deployment": ("placement",),
}
# Short group-id prefixes, one per evidence set.
PREFIX = {
    "servo_calibration": "cal",
    "attachment": "att",
    "release_mode": "rel",
    "delay_sweep": "dly",
    "dynamics": "dyn",
    "held_base": "hb",
    "deployment": "dep",
}

INDEX_COLUMNS = (
    "group_id",
    "evidence_set",
    "category",
    "session",
    "recorded_at",
    "n_mocap",
    "n_servo",
)
GROUP_FILES = ("mocap.parquet", "servo.parquet", "meta.json")

# The cup axis in the tip body's frame: a straight arm hangs along -Y, so with an identity tip
# quaternion the cup points down. The 21-d state uses this axis (paper IV-A: "the tip axis").
TIP_AXIS_LOCAL = (0.0, -1.0, 0.0)


def mocap_columns() -> list[str]:
    cols = ["t"]
    for b in BODIES:
        cols += [f"{b}_{f}" for f in POSE_FIELDS] + [f"{b}_valid"]
    return cols


def servo_columns() -> list[str]:
    cols = ["t"]
    for i in SERVO_IDS:
        cols += [f"goal_{i}", f"present_{i}", f"current_{i}"]
    return cols


def servo_id(section: int, tendon: int) -> int:
    """Servo 3*(s-1)+k pulls tendon k (azimuth 120*(k-1) deg) of section s (both 1-based)."""
    return 3 * (section - 1) + tendon


def tendon_azimuth_deg(tendon: int) -> float:
    return 120.0 * (tendon - 1)


class RecordingError(ValueError):
    """A raw recording breaks the format: one line, `<file>: group <gid>: <what> (rule: <rule>)`."""

    def __init__(self, path, group_id, what, rule):
        self.path, self.group_id, self.what, self.rule = str(path), str(group_id), what, rule
        msg = f"{path}: group {group_id}: {what} (rule: {rule})"
        super().__init__(" ".join(msg.split()))  # one line whatever the pieces hold

    def __reduce__(self):  # picklable across worker processes
        return (type(self), (self.path, self.group_id, self.what, self.rule))


@functools.lru_cache(maxsize=64)
def _real(path: str) -> Path:
    return Path(path).resolve()


def group_dir(raw_dir: str | Path, group_id: str) -> Path:
    """A group's folder. Ids are names, not paths: whatever an id holds (`..`, `/etc`, a
    symlinked folder), the folder must resolve inside `<raw_dir>/groups`, or nothing is read."""
    root = Path(raw_dir) / "groups"
    d = root / str(group_id)
    real_root = _real(str(root))
    gid = str(group_id)
    # a plain name whose folder is not a link resolves under the real root; anything else in full
    plain = gid not in ("", ".", "..") and "/" not in gid and os.sep not in gid and not d.is_symlink()
    real = real_root / gid if plain else d.resolve()
    if real.parent != real_root or real.name != gid:
        raise RecordingError(
            d, group_id, f"resolves to {real}, outside {root}", "group folder inside the raw directory"
        )
    return d


def group_paths(raw_dir: str | Path, group_id: str) -> dict[str, Path]:
    d = group_dir(raw_dir, group_id)
    return {name.split(".")[0]: d / name for name in GROUP_FILES}


def _atomic(path: Path, write) -> None:
    """Write through a temporary file and rename, so a crash never leaves half a file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_parquet(df: pd.DataFrame, path: str | Path) -> None:
    # Fixed writer settings so that the same frame gives the same bytes.
    _atomic(
        Path(path),
        lambda tmp: df.to_parquet(tmp, index=False, engine="pyarrow", compression="zstd"),
    )


def write_json(obj, path: str | Path) -> None:
    def w(tmp):
        with open(tmp, "w") as f:
            json.dump(obj, f, indent=1, sort_keys=True)
            f.write("\n")

    _atomic(Path(path), w)


def write_group(raw_dir: str | Path, meta: dict, mocap: pd.DataFrame, servo: pd.DataFrame) -> None:
    """Write one acquisition group in the rig format (columns ordered as the format says)."""
    p = group_paths(raw_dir, meta["group_id"])
    write_parquet(mocap[mocap_columns()], p["mocap"])
    write_parquet(servo[servo_columns()], p["servo"])
    write_json(meta, p["meta"])


def read_meta(path: str | Path) -> dict:
    with open(path) as f:
        return json.load(f)


def write_index(rows: list[dict], path: str | Path) -> None:
    df = pd.DataFrame(rows, columns=list(INDEX_COLUMNS)).sort_values("group_id")
    _atomic(Path(path), lambda tmp: df.to_csv(tmp, index=False))
