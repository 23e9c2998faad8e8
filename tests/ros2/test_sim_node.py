"""The simulated robot node (dqcontrol/ros2/sim_node.py), driven offline: stand-ins for the
rclpy node and the message classes, the ideal kinematic driver as the robot (no rclpy, no
DDS). Checked against ``q ← q + T u``: the stepped and wall-clock timing, the velocity and
position interfaces, the commands refused, the muted joint states and the report."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.model import LBR4P_Q0
from dqcontrol.ros2 import SimParams
from dqcontrol.ros2 import sim_node as sim_node_module
from dqcontrol.ros2.sim_node import IDLE_REPUBLISH_S, SimNode
from dqcontrol.sim import KinematicDriver

T = 0.01


def _joint_state(name):
    stamp = SimpleNamespace(sec=-1, nanosec=-1)
    return SimpleNamespace(name=name, header=SimpleNamespace(stamp=stamp))


ROS = SimpleNamespace(
    sensor=SimpleNamespace(JointState=_joint_state),
    std=SimpleNamespace(
        String=lambda data: SimpleNamespace(data=data),
        Float64MultiArray="Float64MultiArray",
    ),
    rclpy=SimpleNamespace(
        qos=SimpleNamespace(
            QoSProfile=lambda **kw: SimpleNamespace(**kw),
            ReliabilityPolicy=SimpleNamespace(RELIABLE="reliable"),
            DurabilityPolicy=SimpleNamespace(TRANSIENT_LOCAL="transient local"),
        )
    ),
)


class _Node:
    """What the node uses of an rclpy node: publishers by topic, the command callback, the
    timers and the warnings."""

    def __init__(self) -> None:
        self.sent: dict[str, list] = {}
        self.qos: dict[str, object] = {}
        self.timers: list[SimpleNamespace] = []
        self.warnings: list[str] = []
        self.command = None

    def create_publisher(self, kind, topic, qos):
        self.qos[topic] = qos
        sent = self.sent.setdefault(topic, [])
        return SimpleNamespace(publish=sent.append)

    def create_subscription(self, kind, topic, callback, depth):
        assert kind == "Float64MultiArray" and topic == "/cmd"
        self.command = callback

    def create_timer(self, period_s, callback):
        timer = SimpleNamespace(period_s=period_s, callback=callback, cancelled=False)
        timer.cancel = lambda: setattr(timer, "cancelled", True)
        self.timers.append(timer)
        return timer

    def get_logger(self):
        return SimpleNamespace(warning=self.warnings.append)


@pytest.fixture
def make(lbr4p, monkeypatch):
    """``make(**params)``: the node at rest at the LBR4p's start posture, and its stand-in."""
    monkeypatch.setattr(sim_node_module, "require_ros", lambda: ROS)

    def build(driver=None, **values):
        params = SimParams.from_values({"command_topic": "/cmd", "period_s": T, **values})
        if driver is None:
            driver = KinematicDriver(lbr4p, T)
            driver.reset(LBR4P_Q0)
        node = _Node()
        return SimNode(node, params, lbr4p, driver), node

    return build


def _command(node, values) -> None:
    node.command(SimpleNamespace(data=list(values)))


def _states(node) -> list:
    return node.sent["/joint_states"]


def test_the_description_and_the_state_at_rest_are_published_at_once(make, lbr4p):
    sim, node = make(mode="stepped")
    (description,) = node.sent["/robot_description"]
    assert description.data == lbr4p.source.xml
    assert node.qos["/robot_description"].durability == "transient local"
    (state,) = _states(node)
    assert state.name == list(lbr4p.joint_names) and state.position == list(LBR4P_Q0)
    assert (state.header.stamp.sec, state.header.stamp.nanosec) == (0, 0)
    (idle,) = node.timers  # stepped: the state republished at rest until the first command
    assert idle.period_s == IDLE_REPUBLISH_S
    idle.callback()
    assert len(_states(node)) == 2 and sim.commands == 0


def test_stepped_each_command_steps_one_period(make):
    sim, node = make(mode="stepped")
    u = np.linspace(-0.5, 0.5, 7)
    _command(node, u)
    _command(node, u)
    assert node.timers[0].cancelled and sim.commands == 2
    last = _states(node)[-1]
    np.testing.assert_allclose(last.position, LBR4P_Q0 + 2 * T * u, atol=1e-15)
    np.testing.assert_allclose(last.velocity, u)
    assert (last.header.stamp.sec, last.header.stamp.nanosec) == (0, 20_000_000)


def test_wall_clock_the_timer_steps_with_the_last_command_held(make):
    sim, node = make(mode="wall")
    (tick,) = node.timers
    assert tick.period_s == T
    u = np.full(7, 0.1)
    _command(node, u)
    assert len(_states(node)) == 1  # a command alone does not step on the wall clock
    for _ in range(3):
        tick.callback()
    np.testing.assert_allclose(_states(node)[-1].position, LBR4P_Q0 + 3 * T * u, atol=1e-15)


def test_a_position_target_is_reached_in_one_period_then_held(make):
    sim, node = make(mode="wall", command_interface="position")
    target = LBR4P_Q0 + 0.01
    _command(node, target)
    node.timers[0].callback()
    np.testing.assert_allclose(_states(node)[-1].position, target, atol=1e-12)
    np.testing.assert_allclose(_states(node)[-1].velocity, np.full(7, 0.01 / T))
    node.timers[0].callback()
    np.testing.assert_allclose(_states(node)[-1].position, target, atol=1e-12)
    np.testing.assert_allclose(_states(node)[-1].velocity, 0.0)


def test_bad_commands_are_counted_and_never_step(make):
    sim, node = make(mode="stepped")
    _command(node, [0.0] * 6)
    _command(node, [0.0] * 6 + [float("nan")])
    assert sim.rejected == {"wrong joint count": 1, "non-finite value": 1}
    assert sim.commands == 0 and len(_states(node)) == 1
    assert "(wrong joint count, 1 so far): 6 values for 7 joints" in node.warnings[0]


def test_a_driver_error_is_a_rejection_not_a_crash(make, lbr4p):
    class Unstable(KinematicDriver):
        def write(self, qd_command):
            raise RuntimeError("unstable physics")

    driver = Unstable(lbr4p, T)
    driver.reset(LBR4P_Q0)
    sim, node = make(driver=driver, mode="stepped")
    _command(node, np.zeros(7))
    assert sim.rejected == {"driver error": 1} and len(_states(node)) == 1
    assert "RuntimeError: unstable physics" in node.warnings[0]


def test_muted_the_states_stop_while_the_simulation_goes_on(make):
    sim, node = make(mode="stepped", mute_after=2)
    u = np.full(7, 0.2)
    for _ in range(4):
        _command(node, u)
    assert len(_states(node)) == 1 + 1  # at rest, then the first command's state only
    report = sim.report()
    assert report["commands"] == 4 and report["t_s"] == pytest.approx(4 * T)
    np.testing.assert_allclose(report["q"], LBR4P_Q0 + 4 * T * u, atol=1e-15)


def test_the_report_says_what_was_served(make, tmp_path):
    path = tmp_path / "report.json"
    sim, node = make(mode="stepped", report_file=str(path))
    _command(node, np.full(7, 0.3))
    _command(node, [1.0])
    assert sim.report_line() == "took 1 commands; rejected {'wrong joint count': 1}"
    sim.write_report()
    saved = json.loads(path.read_text())
    assert saved["commands"] == 1 and saved["rejected"] == {"wrong joint count": 1}
    assert saved["last_velocity"] == [0.3] * 7
    quiet, _ = make(mode="stepped")
    assert quiet.report_line() == "took 0 commands; rejected none"
    quiet.write_report()  # no report_file: nothing written
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.json"]
