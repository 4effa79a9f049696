"""The lab file: how one rig's motion capture and servos map onto the recording format.

One YAML file per rig, written once (docs/examples/lab.yaml), validated against
schemas/lab.schema.yaml with Snakemake's `validate`, as the config is. After the schema, the
checks it cannot make: servo ids given twice, axes that are not a proper rotation, a number that is
not finite, three markers of one layout on a line, and two of the arm's bodies on one capture body
(one rigid body, one bone, or one marker in two layouts: the arm would read as zero length there).
Every refusal is one CaptureError line naming the file, the key and the rule.

A body is a Motive rigid body (`rigid_body`), a Motive skeleton bone (`bone`), or a marker
layout fitted frame by frame (`markers`); a fit whose residual passes the configured limit
(config capture.max_marker_residual_mm) refuses the take.

The lab frame is the format's: Y up, metres, quaternions w, x, y, z (docs/data.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..quat import qmul
from ..schemacheck import violation
from .errors import CaptureError
from .rigid import fit_pose

SCHEMA = Path(__file__).resolve().parents[2] / "schemas" / "lab.schema.yaml"
# lab = R @ capture. z_up (Vicon, Qualisys): a quarter turn about X takes the capture's Z to the
# lab's Y and keeps the frame right-handed: lab = (x, z, -y).
AXES = {"y_up": np.eye(3), "z_up": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])}
ROTATION_TOL = 1e-6
# A triangle of markers flatter than this is a line in practice: its rotation about the long side
# would be set by the capture's sub-millimetre noise, and fit_pose accepts a frame that sees 3.
MIN_HEIGHT_M = 1e-3
# sync none: how far the clock shift is searched from the one that lines up the logs' first samples
MAX_OFFSET_S = 0.15
# A body's key in the lab file -> (the Take's table of such bodies, the column type Motive names)
SOLVED = {"rigid_body": ("rigid_bodies", "Rigid Body"), "bone": ("bones", "Bone")}


@dataclass(frozen=True, eq=False)
class Lab:
    path: Path
    rotation: np.ndarray  # (3, 3): lab = rotation @ capture
    bodies: dict[str, dict]  # name -> {"rigid_body": name}, {"bone": name} or {"markers": {label: [x, y, z]}}
    servos: tuple[int, ...]  # bus id behind servo column 1..9
    arm: dict  # arm_length_m, tendon_radius_m, end_effector_m
    clock: dict  # sync ("none", {"column": name} or {"event_time_s": s}), max_drift_ppm, max_offset_s

    def to_lab_frame(self, points) -> np.ndarray:
        """(..., 3) capture coordinates -> lab coordinates."""
        return np.asarray(points, float) @ self.rotation.T

    def body_pose(self, take, name: str, max_residual_m: float):
        """(p (n, 3), q (n, 4) w, x, y, z, valid (n,)) of one body in the lab frame, from a Motive
        Take's rigid body or bone, or from the markers of a Motive Take or a C3D MarkerTake, whose
        fit may leave at most max_residual_m (RMS, any frame)."""
        spec = self.bodies.get(name)
        if spec is None:
            raise CaptureError(
                self.path,
                f"bodies: no {name!r} (it names {', '.join(self.bodies)})",
                "the lab file names base, s1, s2, tip and target",
            )
        key = next((k for k in SOLVED if k in spec), None)
        if key is not None:
            field, kind = SOLVED[key]
            table = getattr(take, field, {}).get(spec[key])
            if table is None:
                # the name under the other kind is a lab file to correct, not a body the take lacks
                other = next((k for k, (f, _) in SOLVED.items() if spec[key] in getattr(take, f, {})), None)
                hint = ""
                if other:
                    hint = f": the take holds it as a {SOLVED[other][1]} (map it with {other}: {spec[key]})"
                raise CaptureError(
                    take.path,
                    f"no {kind.lower()} {spec[key]!r} (the lab file's {name}){hint}",
                    "every body the lab file names is in the take",
                )
            q_axes = Rotation.from_matrix(self.rotation).as_quat(scalar_first=True)
            p = self.to_lab_frame(table[["x", "y", "z"]].to_numpy(float))
            # body -> lab is (capture -> lab) after (body -> capture); NaN (occluded) stays NaN
            q = qmul(q_axes, table[["qw", "qx", "qy", "qz"]].to_numpy(float))
            return p, q, table["valid"].to_numpy(bool)
        # measured markers only: Motive's body_markers are its solver's idealised ones, not data
        missing = [lb for lb in spec["markers"] if lb not in take.markers]
        if missing:
            raise CaptureError(
                take.path,
                f"no marker {missing[0]!r} (the lab file's {name})",
                "every body the lab file names is in the take",
            )
        tables = [take.markers[lb] for lb in spec["markers"]]
        observed = np.stack([np.where(t["valid"].to_numpy()[:, None], t[["x", "y", "z"]], np.nan) for t in tables], 1)
        p, q, valid, residual = fit_pose(list(spec["markers"].values()), self.to_lab_frame(observed))
        worst = np.where(valid, residual, -np.inf)
        k = int(np.argmax(worst)) if len(worst) else 0
        if valid.any() and worst[k] > max_residual_m:
            raise CaptureError(
                take.path,
                f"the lab file's {name} markers fit its layout to {worst[k] * 1e3:.1f} mm RMS at "
                f"t = {take.t[k] - take.t[0]:.3f} s (a layout that is not the body's, or a marker mislabelled?)",
                f"marker fit residual <= {max_residual_m * 1e3:g} mm (config capture.max_marker_residual_mm)",
            )
        return p, q, valid


def read_yaml(path: Path, schema) -> dict:
    """A YAML file checked against its schema (the lab file, a session file): one CaptureError line."""
    import yaml

    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise CaptureError(path, f"not readable ({e.strerror})", "a readable file") from None
    except yaml.YAMLError as e:
        raise CaptureError(path, f"not readable as YAML ({' '.join(str(e).split())})", "a YAML file") from None
    err = violation(doc, schema)
    if err:
        raise CaptureError(path, err, f"the schema {Path(schema).name}")
    return doc


def load_lab(path: str | Path) -> Lab:
    path = Path(path)
    doc = read_yaml(path, SCHEMA)
    _not_finite(path, doc, "")
    servos = tuple(int(i) for i in doc["servos"])
    for col, sid in enumerate(servos, 1):
        if sid in servos[: col - 1]:
            first = servos.index(sid) + 1
            raise CaptureError(
                path,
                f"servos: id {sid} is given twice (servo columns {first} and {col})",
                "each servo id once",
            )
    axes = doc["capture"]["axes"]
    rotation = AXES[axes] if isinstance(axes, str) else np.array(axes, float)
    if not np.abs(rotation @ rotation.T - np.eye(3)).max() <= ROTATION_TOL:
        raise CaptureError(
            path,
            f"capture.axes: the rows are not orthonormal (within {ROTATION_TOL:g})",
            "capture.axes is a rotation",
        )
    if not abs(np.linalg.det(rotation) - 1) <= ROTATION_TOL:
        raise CaptureError(
            path,
            "capture.axes: determinant -1, a reflection (a left-handed frame?)",
            "capture.axes is a rotation",
        )
    owner = {}  # (kind, capture name) -> the arm body mapped to it
    for name, spec in doc["bodies"].items():
        for kind, names in [(k, [spec[k]]) for k in SOLVED if k in spec] + [("marker", spec.get("markers", {}))]:
            for n in names:
                if (kind, n) in owner:
                    raise CaptureError(
                        path,
                        f"bodies.{owner[kind, n]} and bodies.{name} both map to {kind.replace('_', ' ')} {n!r}",
                        "each arm body its own capture body",
                    )
                owner[kind, n] = name
        for labels in combinations(spec.get("markers", {}), 3):
            a, b, c = (np.array(spec["markers"][lb], float) for lb in labels)
            longest = max(np.linalg.norm(b - a), np.linalg.norm(c - b), np.linalg.norm(a - c))
            height = np.linalg.norm(np.cross(b - a, c - a)) / longest if longest > 0 else 0.0
            if height < MIN_HEIGHT_M:
                raise CaptureError(
                    path,
                    f"bodies.{name}.markers: {', '.join(labels)} lie on one line (within 1 mm): "
                    "a frame that sees only them has no rotation about it",
                    "a body's markers span a plane",
                )
    return Lab(path=path, rotation=rotation, bodies=doc["bodies"],
               servos=servos, arm=doc["arm"], clock={"max_offset_s": MAX_OFFSET_S, **doc["clock"]})


def _not_finite(path, value, where):
    # YAML's .nan and .inf are numbers to the schema, and pass its bounds
    if isinstance(value, dict):
        for k, v in value.items():
            _not_finite(path, v, f"{where}.{k}" if where else str(k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _not_finite(path, v, f"{where}.{i}")
    elif isinstance(value, float) and not math.isfinite(value):
        raise CaptureError(path, f"{where}: {value}", "numbers are finite")
