"""The arguments of `esnap deploy`, checked before any port opens (docs/deployment.md, "Arguments
that could move the arm differently").

Pure functions of the parsed arguments and the loaded manifest: each returns the value the trial
will use or raises ArgumentError, one line naming the argument and the rule it breaks. The target
then goes through the manifest's own workspace check (commands.commands), as `client.run` does.
Numpy and the standard library only (the lab PC).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from . import commands as C

# The checks client.run applies again (its one door to the port) live there.
from .client import ArgumentError, DeployError
from .client import checked_baud as baud
from .client import checked_placement as placement
from .client import checked_servo_ids as servo_ids

MOCAP_KEY = "target_m"


def _finite_xyz(values, what: str) -> list[float]:
    """Three finite numbers (bools and strings are not numbers here)."""
    ok = (isinstance(values, (list, tuple)) and len(values) == 3
          and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values))
    try:
        ok = ok and all(math.isfinite(v) for v in values)
    except OverflowError:  # an integer too large for a float
        ok = False
    if not ok:
        raise ArgumentError(f"{what}: expected three finite numbers x, y, z (m, base frame), got {values!r}")
    return [float(v) for v in values]


def parse_target(text: str) -> list[float]:
    """--target x,y,z."""
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = parts
    return _finite_xyz(values, f"--target {text}")


def read_mocap(path) -> list[float]:
    """--target-from-mocap FILE: the mocap export, exactly {"target_m": [x, y, z]} in the base frame.
    Any other key is refused: it may say the numbers mean something else (another frame, unit)."""
    what = f"--target-from-mocap {path}"
    try:
        with open(path) as f:
            data = json.load(f)
    except OSError as e:
        raise ArgumentError(f"{what}: cannot read it ({e.strerror or e})") from None
    except ValueError as e:
        raise ArgumentError(f"{what}: not JSON ({e})") from None
    if not isinstance(data, dict) or set(data) != {MOCAP_KEY}:
        keys = sorted(data) if isinstance(data, dict) else type(data).__name__
        raise ArgumentError(f'{what}: expected exactly {{"{MOCAP_KEY}": [x, y, z]}}, got {keys}')
    return _finite_xyz(data[MOCAP_KEY], f"{what}: {MOCAP_KEY}")


def group_id(gid: str) -> str:
    """--group-id: one folder name under --out (groups/<id>/, aborted/<id>.json), never a path."""
    if not gid or gid in (".", "..") or "/" in gid or "\\" in gid:
        raise ArgumentError(f"--group-id {gid!r}: expected a folder name, not a path")
    return gid


def out_dir(path) -> str | None:
    """--out: a recording tree the trial can be written into, found out before the arm moves
    (else a complete trial would be lost after it): a directory, or one that can be made."""
    if path is None:
        return None
    p = Path(path)
    if not str(path).strip():
        raise ArgumentError("--out: empty path")
    while not p.exists():  # the nearest ancestor that exists must be a directory we may write into
        p = p.parent
    if not p.is_dir() or not os.access(p, os.W_OK):
        raise ArgumentError(f"--out {path}: cannot write there ({p} is not a writable directory)")
    return path


def in_workspace(man: dict, xyz) -> list[float]:
    """The target inside the manifest's target box (commands.commands refuses it otherwise): the
    same refusal, and exit status, as `client.run` gives."""
    try:
        C.commands(man, xyz)
    except C.RefusedTarget as e:
        raise DeployError(f"refused: {e}") from None
    return xyz


def target(man: dict, xyz: str | None, mocap: str | None, k: int | None) -> list[float]:
    """The trial's target: --target, else --target-from-mocap, else placement k's."""
    if xyz is not None:
        t = parse_target(xyz)
    elif mocap is not None:
        t = read_mocap(mocap)
    elif k is not None:
        t = _finite_xyz(man["placements"][k - 1]["target_m"], f"the manifest's placement {k}")
    else:
        raise ArgumentError("give --target, --target-from-mocap or --placement")
    return in_workspace(man, t)


def check(man: dict, a) -> dict:
    """Every argument of `esnap deploy` (argparse namespace `a`) against the manifest, before the
    port opens: {target, baud, placement, group_id, out} as the trial will use them."""
    servo_ids(man)
    k = placement(man, a.placement)
    return dict(target=target(man, a.target, a.target_from_mocap, k), baud=baud(man, a.baud), placement=k,
                group_id=group_id(a.group_id), out=out_dir(a.out))
