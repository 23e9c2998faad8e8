"""A joint driver over ROS 2 topics: ``sensor_msgs/JointState`` in, ``Float64MultiArray`` out.

:class:`Ros2JointDriver` is a :class:`~dqcontrol.sim.driver.JointDriver`, so
:func:`~dqcontrol.sim.run_loop` runs a controller against a ros2_control arm exactly as
against MuJoCo in this process. Each joint state is checked
(:class:`~dqcontrol.ros2.joint_states.JointStateCheck`); a rejected one is counted by
reason and logged, never used. Two timings:

- *wall clock*: :meth:`~Ros2JointDriver.write` publishes and returns; ``read`` gives the
  latest accepted state;
- *stepped* (lockstep with a robot that steps one period per command, as
  ``dqcontrol ros2 sim`` in its stepped mode): ``write`` publishes, then waits for a state
  newer than the last (``timeout_s``; after one missed answer only a period, until states
  come again), so the run is the run in this process, sample for sample.

When the joint states' publisher has left the graph (the robot's node stopped) the driver
raises :class:`RobotGoneError` and publishes nothing more: the loop then stops without a
brake (there is no one to brake).
"""

from __future__ import annotations

import threading
import time
from collections import Counter
from typing import Any

import numpy as np

from dqcontrol.errors import DQControlError
from dqcontrol.ros2.joint_states import JointStateCheck, Rejected
from dqcontrol.sim.mujoco_sim import Measurement

__all__ = ["Ros2JointDriver", "RobotGoneError", "stamp_s"]


class RobotGoneError(DQControlError):
    """The robot's joint states stopped for good (no publisher, or none at the start)."""


def stamp_s(stamp: Any) -> float:
    """A ``builtin_interfaces/Time`` in seconds."""
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


class Ros2JointDriver:
    """Joint states from one topic, commands to another (module docstring).

    Args:
        node: the rclpy node (spun elsewhere: the callbacks fill the latest state).
        ros: the modules of :func:`~dqcontrol.ros2.ros.require_ros`.
        check: the joint-state check; its ``joint_names`` are the command order.
        states_topic: the ``sensor_msgs/JointState`` topic.
        command_topic: the ``std_msgs/Float64MultiArray`` topic of the forward command
            controller.
        period_s: the control period [s].
        stepped: lockstep with the robot (module docstring).
        timeout_s: stepped: how long a command waits for its state [s].
        wait_s: how long the first accepted state may take [s].
    """

    def __init__(
        self, node: Any, ros: Any, check: JointStateCheck, *, states_topic: str,
        command_topic: str, period_s: float, stepped: bool, timeout_s: float, wait_s: float,
    ) -> None:  # fmt: skip
        self._node, self._msg = node, ros.std.Float64MultiArray
        self._check = check
        self.joint_names = check.joint_names
        self.states_topic, self.command_topic = states_topic, command_topic
        self._period_s, self._stepped = period_s, stepped
        self._timeout_s, self._wait_s = timeout_s, wait_s
        self._cond = threading.Condition()
        self._latest: Measurement | None = None
        self._received_at = time.monotonic()
        self._last_rejected = ""
        self._silent = False
        self._gone = False
        self.rejected: Counter[str] = Counter()
        self.accepted = 0
        self.timeouts = 0
        self.commands = 0
        self._pub = node.create_publisher(ros.std.Float64MultiArray, command_topic, 10)
        node.create_subscription(ros.sensor.JointState, states_topic, self._on_state, 10)

    @property
    def meta(self) -> dict:
        """``simulator`` (``"ros2"``), the topics and the timing, for the run log."""
        return {
            "simulator": "ros2",
            "joint_states_topic": self.states_topic,
            "command_topic": self.command_topic,
            "stepped": self._stepped,
        }

    def report(self) -> dict:
        """Counters for the run log: rejected states by reason, accepted states, commands
        published, stepped answers that did not come."""
        return {
            "rejected": dict(self.rejected),
            "accepted": self.accepted,
            "commands": self.commands,
            "timeouts": self.timeouts,
        }

    def _on_state(self, msg: Any) -> None:
        got = self._check.check(
            msg.name, msg.position, msg.velocity, msg.effort, stamp_s(msg.header.stamp)
        )
        if isinstance(got, Rejected):
            self._reject(got)
            return
        with self._cond:
            self._latest = got
            self._received_at = time.monotonic()
            self.accepted += 1
            self._cond.notify_all()

    def _reject(self, why: Rejected) -> None:
        self.rejected[why.reason] += 1
        count = self.rejected[why.reason]
        self._last_rejected = f"{why.reason}: {why.detail}"
        if count == 1 or count % 100 == 0:
            self._node.get_logger().warning(
                f"rejected a JointState on {self.states_topic} ({why.reason}, {count} so "
                f"far): {why.detail}; no command comes from it"
            )

    def read(self) -> Measurement:
        """The latest accepted state (the first: waits up to ``wait_s``).

        Raises:
            RobotGoneError: no accepted state within ``wait_s`` (the message says what was
                rejected, if anything).
        """
        with self._cond:
            if self._latest is None:
                self._cond.wait_for(lambda: self._latest is not None, self._wait_s)
            if self._latest is None:
                last = f"; the last was rejected: {self._last_rejected}" if self.rejected else ""
                raise RobotGoneError(
                    f"no usable sensor_msgs/JointState on {self.states_topic} in "
                    f"{self._wait_s:g} s{last}"
                )
            return self._latest

    def write(self, values: np.ndarray) -> None:
        """Publish one command (joint velocities [rad/s], or positions [rad] through
        :meth:`write_position`) in the command order; stepped: wait for the next state."""
        if self._gone:
            raise RobotGoneError(f"the joint states on {self.states_topic} are gone")
        before = self.read().t_s
        self._pub.publish(self._msg(data=[float(v) for v in values]))
        self.commands += 1
        if self._stepped:
            self._await_state_after(before)
        elif time.monotonic() - self._received_at > 2.0 * self._period_s:
            self._check_publisher()

    write_position = write

    def hold(self) -> None:
        """Command zero velocity (the velocity interface's hold)."""
        self.write(np.zeros(len(self.joint_names)))

    def _await_state_after(self, t_s: float) -> None:
        wait_s = self._period_s if self._silent else self._timeout_s
        with self._cond:
            fresh = self._cond.wait_for(
                lambda: self._latest is not None and self._latest.t_s > t_s, wait_s
            )
        self._silent = not fresh
        if not fresh:
            self.timeouts += 1
            self._check_publisher()

    def _check_publisher(self) -> None:
        if self._node.count_publishers(self.states_topic) == 0:
            self._gone = True
            raise RobotGoneError(
                f"the publisher of {self.states_topic} has left (the robot's node stopped): "
                "no more commands"
            )

    def __repr__(self) -> str:
        return f"Ros2JointDriver({self.states_topic!r} → {self.command_topic!r})"
