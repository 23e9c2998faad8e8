"""The ROS 2 nodes' checks that need no ROS 2 graph: the joint-state check, the parameters,
the path task, and the one-line message when the ``[ros2]`` extra is missing. Nothing here
starts rclpy (tests/ros2/test_nodes.py runs the nodes, in a network namespace)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from dqcontrol.dq.algebra import rotation, translation
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.ros2 import (
    ControlParams,
    JointStateCheck,
    Rejected,
    SimParams,
    trajectory_from_poses,
)

ROOT = Path(__file__).resolve().parents[2]
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


def test_parameters_take_their_defaults_and_checked_values():
    p = ControlParams.from_values({"ee_frame": "flange", "period_s": 1, "joints": ["a", "b"]})
    assert p.period_s == 1.0 and isinstance(p.period_s, float) and p.joints == ("a", "b")
    assert p.controller == "pf" and p.mode == "wall" and p.command_interface == "velocity"
    locked = ControlParams.from_values({"ee_frame": "f", "locked_joints": ["finger=0.01"]})
    assert locked.locks() == {"finger": 0.01}
    assert SimParams.from_values({"q0": [0, 1.5]}).q0 == (0.0, 1.5)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({}, "parameter 'ee_frame' must be the end-effector frame"),
        ({"period_s": -0.01}, "parameter 'period_s' must be finite and > 0 [s], got -0.01"),
        ({"period_s": "fast"}, "parameter 'period_s' must be a number, got 'fast'"),
        ({"mode": "turbo"}, "parameter 'mode' must be one of 'wall', 'stepped', got 'turbo'"),
        ({"controller": "zz"}, "parameter 'controller': unknown controller 'zz'"),
        ({"perod_s": 0.01}, "unknown parameter 'perod_s'; the parameters are: "),
        ({"stale_periods": 0}, "parameter 'stale_periods' must be an integer ≥ 1, got 0"),
        ({"joints": "j1"}, "parameter 'joints' must be a list, got 'j1'"),
        ({"locked_joints": ["finger"]}, "parameter 'locked_joints' must be NAME=VALUE"),
        ({"command_topic": ""}, "parameter 'command_topic' must be a topic name"),
        ({"max_lateness_s": -1.0}, "parameter 'max_lateness_s' must be finite and ≥ 0 [s]"),
        (
            {"realtime_priority": 100},
            "parameter 'realtime_priority': realtime_priority must be an integer in [1, 99]",
        ),
    ],
)
def test_a_bad_parameter_is_one_line_naming_it(values, message):
    values = {"ee_frame": "flange", **values} if "ee_frame" not in values and values else values
    with pytest.raises(ParameterError) as info:
        ControlParams.from_values(values)
    assert str(info.value).startswith(message) and "\n" not in str(info.value)


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


_NO_ROS = textwrap.dedent(
    """
    import sys
    sys.modules["rclpy"] = None
    from dqcontrol.cli import main
    import dqcontrol.ros2  # the package imports without ROS 2
    sys.exit(main(sys.argv[1:]))
    """
)


@pytest.mark.parametrize("node", ["control", "sim"])
def test_without_the_extra_the_commands_say_so_in_one_line(node):
    proc = subprocess.run(
        [sys.executable, "-c", _NO_ROS, "ros2", node, "--ros-args", "-p", "period_s:=0.01"],
        capture_output=True, text=True, timeout=120, cwd=ROOT,
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "[ros2] extra: pip install 'dqcontrol[ros2]'" in lines[0]
