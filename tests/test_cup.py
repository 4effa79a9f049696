"""The cup face from the tracked tip pose (embodied_snap.cup): one definition for the
characterisation's closest approach and attachment features and the policy reward."""

import numpy as np
import pytest

from embodied_snap.cup import cup_from_axis, cup_from_pose, tip_axis
from embodied_snap.quat import from_rotvec

from paper_protocol import PROTO


def test_straight_arm_cup_hangs_below_the_tip():
    tip = np.array([[0.1, 0.7, -0.2]])
    cup = cup_from_pose(tip, np.array([[1.0, 0, 0, 0]]), PROTO.rig.end_effector_m)
    np.testing.assert_allclose(cup, tip + [0.0, -PROTO.rig.end_effector_m, 0.0])


def test_cup_follows_the_tip_axis():
    q = from_rotvec(np.array([[0.0, 0.0, np.pi / 2]]))  # 90 deg about +Z turns -Y into +X
    np.testing.assert_allclose(tip_axis(q), [[1.0, 0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(cup_from_pose(np.zeros((1, 3)), q, 0.15), [[0.15, 0.0, 0.0]], atol=1e-12)
    # an unnormalised axis (the GRU's predicted tip axis) gives the same cup
    np.testing.assert_allclose(cup_from_axis(np.zeros(3), np.array([0.0, -3.0, 4.0]), 0.15), [0.0, -0.09, 0.12])


@pytest.mark.parametrize("ee", [0.0, 0.15])
def test_distance_from_tip_is_the_end_effector(ee):
    rng = np.random.default_rng(1)
    q = from_rotvec(rng.normal(0, 1, (20, 3)))
    tip = rng.normal(0, 1, (20, 3))
    np.testing.assert_allclose(np.linalg.norm(cup_from_pose(tip, q, ee) - tip, axis=1), ee)
