"""What the control node tells (dqcontrol/ros2/status.py): the binding limit of a command,
checked by hand, and ``~/status`` and the RViz markers built as the real ROS 2 messages
(the message classes only: no rclpy context, no DDS)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.extras import has_extra
from dqcontrol.ros2.status import (
    POSITION_MARGIN_RAD,
    VELOCITY_FRACTION,
    Status,
    binding_limit,
    marker_path,
    marker_target,
    status_message,
)

NAMES = ("a", "b", "c")
Q_MIN, Q_MAX, QD_MAX = np.full(3, -1.0), np.full(3, 1.0), np.array([1.0, 2.0, 4.0])

needs_messages = pytest.mark.skipif(not has_extra("ros2"), reason="needs the [ros2] extra")


@pytest.fixture(scope="module")
def messages():
    """The message modules the status and markers are made of."""
    import importlib

    return SimpleNamespace(
        diagnostic=importlib.import_module("diagnostic_msgs.msg"),
        visualization=importlib.import_module("visualization_msgs.msg"),
        geometry=importlib.import_module("geometry_msgs.msg"),
        time=importlib.import_module("builtin_interfaces.msg"),
    )


def _binding(q, u, s=1.0) -> str:
    return binding_limit(NAMES, np.array(q), np.array(u), s, Q_MIN, Q_MAX, QD_MAX)


def test_the_joint_nearest_its_velocity_bound_binds():
    # b at 100 % of its bound, c at 99 %: b is the nearer (largest |u|/qd_max)
    assert _binding([0, 0, 0], [0.1, -2.0, 3.96]) == "velocity b"
    assert _binding([0, 0, 0], [0.0, 0.0, VELOCITY_FRACTION * 4.0]) == "velocity c"
    assert _binding([0, 0, 0], [0.0, 0.0, 0.98 * 4.0]) == "none"


def test_a_joint_at_a_position_limit_binds_only_moving_on():
    near = 1.0 - 0.5 * POSITION_MARGIN_RAD
    assert _binding([0, near, 0], [0, 0.1, 0]) == "position b"
    assert _binding([0, near, 0], [0, 0.0, 0]) == "position b"
    assert _binding([0, near, 0], [0, -0.1, 0]) == "none"  # moving back inside
    assert _binding([-near, 0, 0], [-0.1, 0, 0]) == "position a"
    assert _binding([1.0 - 2 * POSITION_MARGIN_RAD, 0, 0], [0.1, 0, 0]) == "none"


def test_otherwise_the_time_scaling_or_nothing_binds():
    assert _binding([0, 0, 0], [0.1, 0.1, 0.1], s=0.7) == "time scaling"
    assert _binding([0, 0, 0], [0.1, 0.1, 0.1], s=1.0) == "none"
    # a velocity bound comes before the time scaling
    assert _binding([0, 0, 0], [1.0, 0.0, 0.0], s=0.5) == "velocity a"


@needs_messages
def test_the_status_holds_every_key(messages):
    status = Status("stopped", 1.25, 2.0, 0.5, 1.5e-4, "velocity b", "shutdown", 3, "pf", 1)
    msg = status_message(messages, status, None)
    assert isinstance(msg, messages.diagnostic.DiagnosticStatus)
    assert msg.level == bytes([1]) and msg.name == "dqcontrol"
    assert msg.message == "stopped: shutdown"
    values = {kv.key: kv.value for kv in msg.values}
    assert values == {
        "phase": "stopped", "sigma_s": "1.250000", "duration_s": "2.000000", "s": "0.500000",
        "path_deviation_m": "0.000150000", "binding_limit": "velocity b",
        "stop_reason": "shutdown", "rejected_states": "3", "controller": "pf",
    }  # fmt: skip
    assert status_message(messages, Status("running"), None).message == "running"


@needs_messages
def test_the_markers_are_the_path_and_the_target(messages):
    vis = messages.visualization.Marker
    stamp = messages.time.Time(sec=3, nanosec=500)
    points = np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    path = marker_path(messages, "base", points, stamp)
    assert path.type == vis.LINE_STRIP and path.id == 0 and path.ns == "dqcontrol"
    assert path.header.frame_id == "base" and path.header.stamp == stamp
    assert path.scale.x == 0.002
    assert [(p.x, p.y, p.z) for p in path.points] == [(0.1, 0.2, 0.3), (0.4, 0.5, 0.6)]
    # the target's position: the translation of the vec8 (1 + ε t/2) for t = (0.1, -0.2, 0.3)
    target = np.array([1.0, 0, 0, 0, 0, 0.05, -0.1, 0.15])
    sphere = marker_target(messages, "base", target, stamp)
    assert sphere.type == vis.SPHERE and sphere.id == 1 and sphere.header.stamp == stamp
    position = sphere.pose.position
    np.testing.assert_allclose([position.x, position.y, position.z], [0.1, -0.2, 0.3])
    assert sphere.scale.x == sphere.scale.y == sphere.scale.z == 0.01
