"""The nodes' parameters (dqcontrol/ros2/params.py): defaults, coercion to the fields'
types, and one line naming a bad parameter. No rclpy."""

from __future__ import annotations

import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.ros2 import ControlParams, SimParams


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


def test_the_sim_nodes_parameters_take_their_defaults_and_checked_values():
    p = SimParams.from_values({})
    assert (p.robot, p.mode, p.motor, p.period_s, p.mute_after) == (
        "lbr4p", "wall", "velocity", 0.01, -1
    )  # fmt: skip
    p = SimParams.from_values({"motor": "torque", "period_s": 1, "locked_joints": ["f=0.5"]})
    assert p.motor == "torque" and p.period_s == 1.0 and p.locks() == {"f": 0.5}


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"motor": "current"}, "parameter 'motor' must be one of 'velocity', 'torque'"),
        ({"q0": [0.0, float("nan")]}, "parameter 'q0' must be finite joint positions [rad]"),
        ({"q0": ["a"]}, "parameter 'q0' must be a list of numbers"),
        ({"q0": [True]}, "parameter 'q0' must be a list of numbers"),
        ({"mute_after": 1.5}, "parameter 'mute_after' must be an integer, got 1.5"),
        ({"mute_after": True}, "parameter 'mute_after' must be an integer, got True"),
        ({"period_s": 0.0}, "parameter 'period_s' must be finite and > 0 [s], got 0.0"),
        ({"period_s": False}, "parameter 'period_s' must be a number, got False"),
        ({"robot": 3}, "parameter 'robot' must be a string, got 3"),
        ({"joint_states_topic": "a b"}, "parameter 'joint_states_topic' must be a topic name"),
        ({"ee_frame_": "x"}, "unknown parameter 'ee_frame_'; the parameters are: robot, "),
    ],
)
def test_a_bad_sim_parameter_is_one_line_naming_it(values, message):
    with pytest.raises(ParameterError) as info:
        SimParams.from_values(values)
    assert str(info.value).startswith(message) and "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"exit_when_done": "yes"}, "parameter 'exit_when_done' must be true or false"),
        ({"joints": ["j1", 2]}, "parameter 'joints' must be a list of strings"),
        ({"status_every": 0}, "parameter 'status_every' must be an integer ≥ 1, got 0"),
        ({"task": "square"}, "parameter 'task' must be one of 'circle', 'sinusoid', 'path'"),
        ({"servo_time_constant_s": float("inf")}, "parameter 'servo_time_constant_s' must be"),
    ],
)
def test_more_bad_control_parameters(values, message):
    with pytest.raises(ParameterError, match=message.replace("(", r"\(").replace("[", r"\[")):
        ControlParams.from_values({"ee_frame": "flange", **values})


def test_a_zero_servo_time_constant_and_lateness_are_allowed():
    p = ControlParams.from_values(
        {"ee_frame": "f", "servo_time_constant_s": 0.0, "max_lateness_s": 0, "exit_when_done": True}
    )
    assert p.servo_time_constant_s == 0.0 and p.max_lateness_s == 0.0 and p.exit_when_done
