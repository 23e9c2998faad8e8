"""The control node (dqcontrol/ros2/control_node.py), the parts that need no ROS 2 graph: the
outcome and timing lines of a finished task, ``~/stop``, a ``nav_msgs/Path`` turned into a
task, the sample callback and the controller built from the parameters. A stand-in node,
no rclpy, no DDS (tests/ros2/test_nodes.py runs the node over ROS 2 in a namespace)."""

from __future__ import annotations

import queue
from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.dq.algebra import rotation, translation
from dqcontrol.model import LBR4P_Q0
from dqcontrol.ros2 import ControlParams
from dqcontrol.ros2 import control_node as control_node_module
from dqcontrol.ros2.control_node import (
    ERROR,
    OK,
    WARN,
    ControlNode,
    StopRequested,
    _outcome,
    _timing,
)
from dqcontrol.trajectories import WaypointTrajectory


def _result(reason: str = "", completed: bool = True, note: str = ""):
    return SimpleNamespace(reason=reason, note=note, metrics=SimpleNamespace(completed=completed))


@pytest.mark.parametrize(
    ("reason", "completed", "requested", "expected"),
    [
        ("", True, False, ("done", "", OK)),
        ("", False, False,
         ("stopped", "time limit before the end of the task: braked, holding", WARN)),
        ("user", False, True, ("stopped", "stop requested on ~/stop: braked to rest, holding",
                               WARN)),
        ("user", False, False, ("stopped", "shutdown: braked to rest, holding", WARN)),
        ("stale", False, False, ("stopped", "stale joint states (why): braked, holding", WARN)),
        ("simulation", False, False,
         ("stopped", "robot gone, no more commands (why)", ERROR)),
        ("deadline", False, False, ("stopped", "missed deadline (why): braked, holding", WARN)),
    ],
)  # fmt: skip
def test_the_outcome_of_a_task(reason, completed, requested, expected):
    assert _outcome(_result(reason, completed, "why"), requested) == expected


def test_the_timing_line_only_on_the_wall_clock():
    assert _timing({"reason": "done"}) == ""
    stop = {"jitter_median_ms": 0.0123, "jitter_p99_ms": 0.5, "jitter_max_ms": 2.25,
            "missed_deadlines": 4}  # fmt: skip
    assert _timing(stop) == (
        "; start jitter median 0.012 / p99 0.500 / max 2.250 ms, late commands 4"
    )


def test_a_stop_request_is_a_keyboard_interrupt():
    assert issubclass(StopRequested, KeyboardInterrupt)  # the loop brakes on it as on Ctrl-C


class _Node:
    def __init__(self) -> None:
        self.logged: list[tuple[str, str]] = []

    def get_logger(self):
        return SimpleNamespace(
            info=lambda m: self.logged.append(("info", m)),
            error=lambda m: self.logged.append(("error", m)),
        )


@pytest.fixture
def control(lbr4p, monkeypatch):
    """A control node on the LBR4p, as after :meth:`ControlNode.start`, its arm at the start
    posture (a stand-in driver)."""
    monkeypatch.setattr(control_node_module, "require_ros", lambda: SimpleNamespace())
    node = ControlNode(_Node(), ControlParams.from_values({"ee_frame": "lbr4p_flange"}))
    node.robot, node.frame, node._perm = lbr4p, "base", None
    node.driver = SimpleNamespace(read=lambda: SimpleNamespace(q=LBR4P_Q0), rejected={})
    return node


def test_stop_answers_whether_a_task_runs(control):
    idle = control._on_stop(None, SimpleNamespace())
    assert idle.success is False and idle.message == "no task is running"
    assert not control._stop.is_set()
    control._running.set()
    running = control._on_stop(None, SimpleNamespace())
    assert running.success and running.message == "stopping: braking to rest, then holding"
    assert control._stop.is_set()


def _path_msg(frame: str, positions, quats, stamps):
    poses = [
        SimpleNamespace(
            pose=SimpleNamespace(
                position=SimpleNamespace(x=p[0], y=p[1], z=p[2]),
                orientation=SimpleNamespace(w=q[0], x=q[1], y=q[2], z=q[3]),
            ),
            header=SimpleNamespace(stamp=SimpleNamespace(sec=int(t), nanosec=0)),
        )
        for p, q, t in zip(positions, quats, stamps, strict=True)
    ]
    return SimpleNamespace(header=SimpleNamespace(frame_id=frame), poses=poses)


def test_a_path_in_the_base_frame_becomes_the_next_task(control, lbr4p):
    start = lbr4p.pose(LBR4P_Q0)
    positions = translation(start) + np.array([[0, 0, 0], [0, 0.02, 0], [0, 0.02, 0.02]])
    quats = np.tile(rotation(start), (3, 1))
    control._on_path(_path_msg("base", positions, quats, [10, 11, 13]))
    task = control._tasks.get_nowait()
    np.testing.assert_allclose(task[0], positions)
    np.testing.assert_allclose(task[2], [10.0, 11.0, 13.0])
    trajectory = control._trajectory(task)
    assert isinstance(trajectory, WaypointTrajectory) and trajectory.duration == 3.0
    np.testing.assert_allclose(translation(trajectory.target(3.0)), positions[-1], atol=1e-12)


def test_a_path_is_refused_in_another_frame_or_while_a_task_runs(control, lbr4p):
    start = lbr4p.pose(LBR4P_Q0)
    positions = np.tile(translation(start), (2, 1))
    quats = np.tile(rotation(start), (2, 1))
    control._on_path(_path_msg("world", positions, quats, [0, 1]))
    control._running.set()
    control._on_path(_path_msg("base", positions, quats, [0, 1]))
    assert control._tasks.empty()
    (first, second) = [m for kind, m in control.node.logged if kind == "error"]
    assert "in frame 'world'" in first and "robot's base frame 'base'" in first
    assert "a task is running (call ~/stop first)" in second


def test_the_parameters_task_is_the_thesis_trajectory(control):
    trajectory = control._trajectory("sinusoid")
    assert type(trajectory).__name__ == "Sinusoid" and trajectory.duration == 2.0


def test_the_controller_is_the_registrys_with_the_servo_lag(lbr4p, monkeypatch):
    monkeypatch.setattr(control_node_module, "require_ros", lambda: SimpleNamespace())
    calls = []
    monkeypatch.setattr(
        control_node_module, "build_controller", lambda *a, **kw: calls.append((a, kw))
    )
    params = {"ee_frame": "f", "controller": "p10", "period_s": 0.02}
    for lag in (0.0, 0.005):
        node = ControlNode(
            _Node(), ControlParams.from_values({**params, "servo_time_constant_s": lag})
        )
        node.robot = lbr4p
        node.build("TRAJ")
    assert calls == [
        (("p10", lbr4p, "TRAJ", 0.02), {"shared": {}}),
        (("p10", lbr4p, "TRAJ", 0.02), {"shared": {"servo_time_constant_s": 0.005}}),
    ]
    assert node.stop_policy() == "brake"


def test_the_sampler_hands_every_nth_sample_over_and_raises_the_stop(lbr4p, monkeypatch):
    monkeypatch.setattr(control_node_module, "require_ros", lambda: SimpleNamespace())
    node = ControlNode(_Node(), ControlParams.from_values({"ee_frame": "f", "status_every": 3}))
    reports: queue.SimpleQueue = queue.SimpleQueue()
    on_sample = node._sampler(None, reports)
    driver = SimpleNamespace(read=lambda: SimpleNamespace(q=LBR4P_Q0))
    for k in range(7):
        on_sample(k, driver, f"result{k}")
    handed = [reports.get_nowait() for _ in range(reports.qsize())]
    assert [(k, r) for k, _q, r in handed] == [(0, "result0"), (3, "result3"), (6, "result6")]
    np.testing.assert_array_equal(handed[0][1], LBR4P_Q0)
    node._stop.set()
    with pytest.raises(StopRequested):
        on_sample(7, driver, "result7")
