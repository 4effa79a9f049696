"""The cup face from the tracked tip pose: one definition for the characterisation (closest
approach, attachment features, Fig. 3c) and the policy reward.

The compliant end effector beyond the tracked tip (distal end of S3) is not tracked; its cups sit
`end_effector_m` (config rig.end_effector_m) along the tip axis, the tip frame's local
rawformat.TIP_AXIS_LOCAL (-Y: a straight arm hangs along -Y, so the cup points down).
"""

from __future__ import annotations

import numpy as np

from .quat import qrotate
from .rawformat import TIP_AXIS_LOCAL


def cup_from_axis(tip: np.ndarray, axis: np.ndarray, end_effector_m: float) -> np.ndarray:
    """Cup face (..., 3): the tip position (..., 3) plus end_effector_m along the tip axis
    (..., 3, any length: normalised here)."""
    axis = np.asarray(axis, float)
    return np.asarray(tip, float) + end_effector_m * axis / np.linalg.norm(axis, axis=-1, keepdims=True)


def tip_axis(quat: np.ndarray) -> np.ndarray:
    """Tip axis (..., 3) in the lab from the tip orientation (..., 4: w, x, y, z)."""
    return qrotate(np.asarray(quat, float), np.array(TIP_AXIS_LOCAL))


def cup_from_pose(tip: np.ndarray, quat: np.ndarray, end_effector_m: float) -> np.ndarray:
    """Cup face (..., 3) from the tracked tip pose: position (..., 3), orientation (..., 4)."""
    return cup_from_axis(tip, tip_axis(quat), end_effector_m)
