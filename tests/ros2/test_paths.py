"""A ``nav_msgs/Path`` as a task (dqcontrol/ros2/paths.py): the trajectory through its poses
in the base frame, and the paths refused with what is wrong. No rclpy."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.dq.algebra import rotation, translation
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.ros2 import trajectory_from_poses


def test_a_path_becomes_a_trajectory_in_the_base_frame(lbr4p):
    start = lbr4p.pose(LBR4P_Q0)
    p0, r0 = translation(start), rotation(start)
    positions = p0 + np.array([[0, 0, 0], [0.02, 0, 0], [0.02, 0.02, 0]])
    traj = trajectory_from_poses(positions, np.tile(r0, (3, 1)), [5.0, 5.5, 6.5], start, 0.01)
    assert traj.duration == pytest.approx(1.5)
    np.testing.assert_allclose(translation(traj.target(1.5)), positions[-1], atol=1e-12)
    np.testing.assert_allclose(translation(traj.target(0.0)), p0, atol=1e-12)


@pytest.mark.parametrize(
    ("shift_m", "stamps", "message"),
    [
        (0.0, [0.0], "at least 2 poses"),
        (0.0, [0.0, 0.0, 1.0], "strictly increasing"),
        (0.05, [0.0, 0.5, 1.0], "the path starts 86.6 mm from the end effector"),
    ],
)
def test_a_bad_path_is_refused_with_what_is_wrong(lbr4p, shift_m, stamps, message):
    start = lbr4p.pose(LBR4P_Q0)
    n = len(stamps)
    positions = translation(start) + shift_m + np.linspace(0, 0.02, n)[:, None]  # x, y, z
    quats = np.tile(rotation(start), (n, 1))
    with pytest.raises(ParameterError, match=message):
        trajectory_from_poses(positions, quats, stamps, start, 0.01)


def test_a_path_turned_from_the_end_effector_is_refused_with_the_angle(lbr4p):
    start = lbr4p.pose(LBR4P_Q0)
    r0 = rotation(start)
    half = 0.05  # a turn of 0.1 rad about x, applied to the start orientation
    turn = np.array([np.cos(half), np.sin(half), 0.0, 0.0])
    w0, v0 = turn[0], turn[1:]
    w1, v1 = r0[0], r0[1:]
    turned = np.r_[w0 * w1 - v0 @ v1, w0 * v1 + w1 * v0 + np.cross(v0, v1)]
    positions = translation(start) + np.array([[0, 0, 0], [0.02, 0, 0]])
    with pytest.raises(ParameterError, match=r"first orientation is 0\.100 rad from the end"):
        trajectory_from_poses(positions, np.tile(turned, (2, 1)), [0.0, 1.0], start, 0.01)
    # the same orientation with the other sign of its quaternion is accepted
    traj = trajectory_from_poses(positions, np.tile(-r0, (2, 1)), [0.0, 1.0], start, 0.01)
    assert traj.duration == pytest.approx(1.0)
