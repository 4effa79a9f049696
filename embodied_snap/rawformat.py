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


# The raw directory is closed: every file the gate or a job opens under it must really be there.
# A symlink that stays inside is allowed (a deduplicated store under raw_data/); one that leads out
# (a file, a group folder, groups/ itself) is refused before anything is opened, so the bytes the
# gate checked are the raw directory's and nothing elsewhere (/etc/passwd) is ever read.
FILE_RULE = "file inside the raw directory"
FOLDER_RULE = "group folder inside the raw directory"


@functools.lru_cache(maxsize=64)
def _real_dir(cwd: str, path: str) -> str:
    return os.path.join(os.path.realpath(os.path.join(cwd, path)), "")


def _outside(path: Path, raw_dir) -> str | None:
    """Where a link really leads, if that is outside raw_dir (None: it stays inside)."""
    real = os.path.realpath(path)
    return None if real.startswith(_real_dir(os.getcwd(), str(raw_dir))) else real


def raw_file(raw_dir: str | Path, name: str, group_id: str = "-") -> Path:
    """`<raw_dir>/<name>` (index.csv, sealed.json), refused if it resolves outside raw_dir."""
    p = Path(raw_dir) / name
    real = _outside(p, raw_dir) if os.path.islink(p) else None
    if real:
        raise RecordingError(p, group_id, f"a link to {real}, outside {raw_dir}", FILE_RULE)
    return p


def group_dir(raw_dir: str | Path, group_id: str) -> Path:
    """A group's folder. Ids are names, not paths: whatever an id holds (`..`, `/etc`, a
    symlinked folder), the folder must resolve inside `raw_dir`, or nothing is read."""
    root = Path(raw_dir) / "groups"
    gid = str(group_id)
    d = root / gid
    if gid in ("", ".", "..") or "/" in gid or os.sep in gid:  # ids are names, not paths
        raise RecordingError(d, group_id, f"resolves to {d.resolve()}, not a folder of {root}", FOLDER_RULE)
    # Plain folders (one lstat each) cannot lead out; a link is followed to its end.
    real = _outside(d, raw_dir) if os.path.islink(root) or os.path.islink(d) else None
    if real:
        raise RecordingError(d, group_id, f"resolves to {real}, outside {raw_dir}", FOLDER_RULE)
    return d


def group_paths(raw_dir: str | Path, group_id: str) -> dict[str, Path]:
    """A group's three files, each refused if it resolves outside raw_dir. Checked here, so every
    reader (the gate, the jobs: resampling, the fits) gets only paths that stay inside."""
    d = group_dir(raw_dir, group_id)
    out = {}
    for name in GROUP_FILES:
        p = d / name
        real = _outside(p, raw_dir) if os.path.islink(p) else None  # inside a checked folder
        if real:
            raise RecordingError(p, group_id, f"a link to {real}, outside {raw_dir}", FILE_RULE)
        out[name.split(".")[0]] = p
    return out


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
