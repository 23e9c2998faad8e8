"""The check of each joint state (dqcontrol/ros2/joint_states.py): the mapping by name into
the command order, and every reason a message is rejected. No rclpy."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.ros2 import JointStateCheck, Rejected
from dqcontrol.ros2.joint_states import REASONS

NAMES = [f"j{i}" for i in range(1, 4)]


def test_a_joint_state_is_mapped_by_name_into_the_command_order():
    check = JointStateCheck(NAMES, locked_names=("finger",))
    m = check.check(["j3", "finger", "j1", "j2"], [3.0, 9.0, 1.0, 2.0], [], [], 1.5)
    assert not isinstance(m, Rejected)
    np.testing.assert_array_equal(m.q, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(m.qd, [0.0, 0.0, 0.0])
    assert m.t_s == 1.5 and np.isnan(m.torque).all()


@pytest.mark.parametrize(
    ("names", "position", "velocity", "reason"),
    [
        (NAMES, [0.0, float("nan"), 0.0], [], "non-finite"),
        (NAMES, [0.0, 0.0, 0.0], [0.0, float("inf"), 0.0], "non-finite"),
        (NAMES, [0.0, 0.0], [], "wrong length"),
        (NAMES, [0.0, 0.0, 0.0], [0.0], "wrong length"),
        (["j1", "j2", "elbow"], [0.0, 0.0, 0.0], [], "unknown joints"),
        (["j1", "j2"], [0.0, 0.0], [], "missing joints"),
        (["j1", "j1", "j2", "j3"], [0.0] * 4, [], "duplicate names"),
    ],
)
def test_a_bad_joint_state_is_rejected_with_its_reason(names, position, velocity, reason):
    got = JointStateCheck(NAMES).check(names, position, velocity)
    assert isinstance(got, Rejected) and got.reason == reason and got.detail


def test_efforts_are_mapped_and_their_magnitude_is_the_peak():
    m = JointStateCheck(NAMES).check(
        ["j2", "j3", "j1"], [2.0, 3.0, 1.0], [0.2, 0.3, 0.1], [-2.0, 3.0, -1.0], 4.0
    )
    assert not isinstance(m, Rejected)
    np.testing.assert_array_equal(m.q, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(m.qd, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(m.torque, [-1.0, -2.0, 3.0])
    np.testing.assert_array_equal(m.torque_peak, [1.0, 2.0, 3.0])


def test_a_non_finite_stamp_is_rejected():
    got = JointStateCheck(NAMES).check(NAMES, [0.0, 0.0, 0.0], [], [], float("nan"))
    assert isinstance(got, Rejected) and got.reason == "non-finite" and got.reason in REASONS


@pytest.mark.parametrize(
    ("names", "locked"), [([], ()), (["a", "a"], ()), (["a", "b"], ("b",)), ([], ("a",))]
)
def test_the_joints_must_be_distinct_and_one_at_least(names, locked):
    with pytest.raises(ParameterError, match="must be distinct names, at least one controlled"):
        JointStateCheck(names, locked)
