"""The joint driver over ROS 2 topics (dqcontrol/ros2/driver.py), driven offline: a stand-in
node records what is published and delivers joint states to the driver's callback by
hand (no rclpy, no DDS). Checked: accepted and rejected states, the commands published,
the stepped lockstep and its timeouts, and a robot whose publisher has left."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.ros2 import JointStateCheck
from dqcontrol.ros2.driver import RobotGoneError, Ros2JointDriver, stamp_s

NAMES = ("j1", "j2")
ROS = SimpleNamespace(
    std=SimpleNamespace(Float64MultiArray=lambda data: SimpleNamespace(data=data)),
    sensor=SimpleNamespace(JointState="JointState"),
)


class _Publisher:
    def __init__(self) -> None:
        self.sent: list = []
        self.answer = None  # called with each message published (a robot's reply)

    def publish(self, msg) -> None:
        self.sent.append(msg)
        if self.answer is not None:
            self.answer(msg)


class _Node:
    """What the driver uses of an rclpy node."""

    def __init__(self) -> None:
        self.publisher = _Publisher()
        self.publishers_of_states = 1
        self.warnings: list[str] = []
        self.deliver = None

    def create_publisher(self, kind, topic, depth):
        assert kind is ROS.std.Float64MultiArray and topic == "/cmd" and depth == 10
        return self.publisher

    def create_subscription(self, kind, topic, callback, depth):
        assert kind == "JointState" and topic == "/js" and depth == 10
        self.deliver = callback

    def get_logger(self):
        return SimpleNamespace(warning=self.warnings.append)

    def count_publishers(self, topic):
        assert topic == "/js"
        return self.publishers_of_states


def _state(t_s: float, position=(0.1, 0.2), names=NAMES):
    sec = int(t_s)
    stamp = SimpleNamespace(sec=sec, nanosec=round((t_s - sec) * 1e9))
    return SimpleNamespace(
        name=list(names), position=list(position), velocity=[], effort=[],
        header=SimpleNamespace(stamp=stamp),
    )  # fmt: skip


def _driver(*, stepped=False, period_s=0.01, timeout_s=0.05, wait_s=0.02):
    node = _Node()
    driver = Ros2JointDriver(
        node, ROS, JointStateCheck(NAMES), states_topic="/js", command_topic="/cmd",
        period_s=period_s, stepped=stepped, timeout_s=timeout_s, wait_s=wait_s,
    )  # fmt: skip
    return node, driver


def test_a_stamp_is_seconds_and_nanoseconds():
    assert stamp_s(SimpleNamespace(sec=3, nanosec=250_000_000)) == 3.25
    assert stamp_s(SimpleNamespace(sec=0, nanosec=1)) == 1e-9


def test_the_latest_accepted_state_is_read():
    node, driver = _driver()
    node.deliver(_state(0.5, (0.1, 0.2)))
    node.deliver(_state(0.51, (0.3, 0.4), names=("j2", "j1")))
    m = driver.read()
    assert m.t_s == pytest.approx(0.51)
    np.testing.assert_array_equal(m.q, [0.4, 0.3])  # in the command order
    assert driver.meta == {
        "simulator": "ros2", "joint_states_topic": "/js", "command_topic": "/cmd",
        "stepped": False,
    }  # fmt: skip
    assert driver.report() == {"rejected": {}, "accepted": 2, "commands": 0, "timeouts": 0}


def test_rejected_states_are_counted_logged_and_never_read():
    node, driver = _driver()
    for _ in range(100):
        node.deliver(_state(0.5, (0.1,)))  # one position for two names
    node.deliver(_state(0.5, (0.1, float("nan"))))
    assert driver.rejected == {"wrong length": 100, "non-finite": 1}
    assert len(node.warnings) == 3  # the first of each reason, and the 100th
    assert "(wrong length, 100 so far)" in node.warnings[1]
    with pytest.raises(RobotGoneError) as info:
        driver.read()
    message = str(info.value)
    assert message.startswith("no usable sensor_msgs/JointState on /js in 0.02 s")
    assert "; the last was rejected: non-finite: a position, velocity or stamp" in message


def test_no_state_at_all_says_so():
    _node, driver = _driver()
    with pytest.raises(RobotGoneError, match=r"on /js in 0.02 s$"):
        driver.read()


def test_a_command_is_published_in_the_command_order_as_floats():
    node, driver = _driver()
    node.deliver(_state(0.0))
    driver.write(np.array([1, -2]))
    driver.hold()
    assert [m.data for m in node.publisher.sent] == [[1.0, -2.0], [0.0, 0.0]]
    assert all(type(v) is float for v in node.publisher.sent[0].data)
    assert driver.commands == 2 and driver.write_position == driver.write


def test_stepped_a_command_waits_for_the_state_after_it():
    node, driver = _driver(stepped=True)
    node.deliver(_state(0.0))
    clock = iter(np.arange(1, 10) * 0.01)
    node.publisher.answer = lambda _msg: node.deliver(_state(next(clock)))
    driver.write(np.zeros(2))
    driver.write(np.zeros(2))
    assert driver.read().t_s == pytest.approx(0.02) and driver.timeouts == 0


def test_stepped_a_missing_answer_is_counted_and_a_gone_robot_stops_the_commands():
    node, driver = _driver(stepped=True, timeout_s=0.01)
    node.deliver(_state(0.0))
    driver.write(np.zeros(2))  # nobody answers, the publisher is still there
    assert driver.timeouts == 1
    node.publishers_of_states = 0
    with pytest.raises(RobotGoneError, match="publisher of /js has left"):
        driver.write(np.zeros(2))
    assert driver.timeouts == 2
    with pytest.raises(RobotGoneError, match="the joint states on /js are gone"):
        driver.write(np.zeros(2))
    assert driver.commands == 2  # nothing published once gone


def test_wall_clock_a_silent_robot_without_a_publisher_is_gone():
    node, driver = _driver(period_s=1e-9)
    node.deliver(_state(0.0))
    driver.write(np.zeros(2))  # old state, but the publisher is there
    node.publishers_of_states = 0
    with pytest.raises(RobotGoneError, match="has left"):
        driver.write(np.zeros(2))
