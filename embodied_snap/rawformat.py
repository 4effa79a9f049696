"""The rig recording format, version 1 (docs/design.md section 2): the one place that names it.

Lab frame in metres, Y up. Servo positions in Dynamixel ticks (XM430-W350-R, 4096 ticks/rev).
Every writer (simulated rig, deployment recorder) and every reader (validation, resampling)
takes its column names from here.
"""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path
from typing import NamedTuple

import pandas as pd

from .files import write_atomic
from .io import write_json, write_parquet

FORMAT_VERSION = 1
# Mocap may be recorded at any constant rate in this range (Hz, both ends included): the gate reads
# the rate off the recording's own timestamps (rawschema, rule MOCAP_RATE_RULE), and nothing
# downstream assumes one rate.
MOCAP_HZ_RANGE = (100.0, 500.0)
MOCAP_RATE_RULE = f"mocap rate constant, {MOCAP_HZ_RANGE[0]:g}-{MOCAP_HZ_RANGE[1]:g} Hz"
# The simulated rig's capture rate (twin/mocap.py, the tests' fake rig): what it records, not
# what the format requires. The gate and the pipeline never read it.
MOCAP_HZ = 240.0
SERVO_HZ = 100.0
# When the goal logged in a servo-log row began to act (meta.json `goal_timing`, one of these):
# "interval" -- somewhere in the interval since the previous row (the goals run at the servo loop's
# own rate and the log samples them: the simulated rig); "row" -- written in the row's own bus
# cycle, just before its sync-read (esnap lab and esnap deploy log so, as a live bus does).
# Recordings without the key are "interval".
GOAL_INTERVAL, GOAL_ROW = "interval", "row"
GOAL_TIMING = (GOAL_INTERVAL, GOAL_ROW)
TICKS_PER_REV = 4096
N_SERVOS = 9

BODIES = ("base", "s1", "s2", "tip", "target")
POSE_FIELDS = ("x", "y", "z", "qw", "qx", "qy", "qz")
SERVO_IDS = tuple(range(1, N_SERVOS + 1))


class EvidenceSet(NamedTuple):
    prefix: str  # of its group ids, `<prefix>_<nnnn>`
    categories: tuple  # paper Table I and section IV-A, in group-numbering order
    budgeted: bool = True  # recorded as a budget's `groups` ask (deployment: by the deployment stage)


# The evidence sets: the one table that names them and their categories (docs/data.md), in plan
# order. A budget's `groups` (config.yaml) asks for counts per set and category of this table;
# the gate's labels and programs per set (config.yaml `gate`) and the separation policy
# (lineage/policy.py) are keyed by these names.
EVIDENCE = {
    "servo_calibration": EvidenceSet("cal", ("burst",)),
    "attachment": EvidenceSet("att", ("target",)),
    "release_mode": EvidenceSet("rel", ("direct", "ramped", "instantaneous")),
    "delay_sweep": EvidenceSet("dly", ("sweep",)),
    "dynamics": EvidenceSet("dyn", ("free_space", "target", "sealed", "pilot", "characterisation")),
    "held_base": EvidenceSet("hb", ("held",)),
    "deployment": EvidenceSet("dep", ("placement",), budgeted=False),
}
EVIDENCE_SETS = tuple(EVIDENCE)
CATEGORIES = {es: e.categories for es, e in EVIDENCE.items()}
PREFIX = {es: e.prefix for es, e in EVIDENCE.items()}


def groups_error(config: dict) -> str | None:
    """One line naming a budget's `groups` key that is not a budgeted evidence set of EVIDENCE, or
    not one of its categories (as the schema's errors read); None if all are."""
    for b, spec in config["budgets"].items():
        for es, counts in spec["groups"].items():
            where = f"config: budgets.{b}.groups"
            if es not in EVIDENCE or not EVIDENCE[es].budgeted:
                known = ", ".join(k for k, e in EVIDENCE.items() if e.budgeted)
                return (f"{where}: {es!r} is not an evidence set a budget records (known: {known}; "
                        "embodied_snap/rawformat.py)")
            for cat in counts:
                if cat not in EVIDENCE[es].categories:
                    return (f"{where}.{es}: {cat!r} is not a category of {es} (known: "
                            f"{', '.join(EVIDENCE[es].categories)}; embodied_snap/rawformat.py)")
    return None

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


def goal_timing(meta: dict) -> str:
    """The servo log's goal timing (GOAL_TIMING); the gate has checked the value."""
    return meta.get("goal_timing", GOAL_INTERVAL)


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
    write_atomic(path, lambda tmp: df.to_csv(tmp, index=False))
