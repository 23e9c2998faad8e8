"""The robot in MuJoCo as a ros2_control arm: ``/joint_states`` and ``robot_description``
out, a forward command controller's ``Float64MultiArray`` in (docs/ros2.md).

:class:`SimNode` serves a :class:`~dqcontrol.sim.MujocoDriver` (or any simulated driver):

- *wall clock*: a ROS timer steps the simulation one period with the command held (the
  last velocity; for a position interface, the velocity that reaches the last target in
  one period, then zero) and publishes the state;
- *stepped*: each command steps the simulation one period and publishes the state; the
  state at rest is published every 0.1 s until the first command, so a late subscriber
  gets it.

A command is checked as the sim-server checks its packets (:class:`~dqcontrol.sim.SimServer`):
the wrong joint count and non-finite values are rejected, a driver error (e.g. unstable
physics) too; each is counted by reason, logged, and never steps the robot.
``mute_after`` (a test's fault) stops publishing the joint states after that many commands
while the simulation goes on taking them.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from dqcontrol.model.robot import RobotModel
from dqcontrol.ros2.params import SimParams
from dqcontrol.ros2.robot_source import description_qos
from dqcontrol.ros2.ros import require_ros
from dqcontrol.sim.mujoco_sim import Measurement

__all__ = ["SimNode"]

#: Stepped mode: the period [s] of the state republished at rest before the first command.
IDLE_REPUBLISH_S = 0.1


class SimNode:
    """A simulated arm behind ros2_control's topics (module docstring).

    Args:
        node: the rclpy node.
        params: the checked parameters.
        robot: the robot (its URDF text is published on ``robot_description``).
        driver: a simulated driver of ``robot`` (``reset``, ``write``, ``read``), at rest.
    """

    def __init__(self, node: Any, params: SimParams, robot: RobotModel, driver: Any) -> None:
        ros = require_ros()
        self.ros, self.node, self.params, self.driver = ros, node, params, driver
        self.joint_names = tuple(driver.joint_names)
        self.n = len(self.joint_names)
        self.rejected: Counter[str] = Counter()
        self.commands = 0
        self._log = node.get_logger()
        self._state: Measurement = driver.read()
        self._held = np.zeros(self.n)  # velocity interface: the command held [rad/s]
        self._target = np.array(self._state.q, dtype=float)  # position interface [rad]
        self._reached = self._target.copy()
        self._pub = node.create_publisher(ros.sensor.JointState, params.joint_states_topic, 10)
        text = robot.source.xml if robot.source is not None else ""
        description = node.create_publisher(
            ros.std.String, params.robot_description_topic, description_qos(ros)
        )
        description.publish(ros.std.String(data=text))
        node.create_subscription(
            ros.std.Float64MultiArray, params.command_topic, self._on_command, 10
        )
        if params.mode == "wall":
            node.create_timer(params.period_s, self._tick)
        else:
            self._idle = node.create_timer(IDLE_REPUBLISH_S, self._publish_state)
        self._publish_state()

    def _on_command(self, msg: Any) -> None:
        values = np.asarray(msg.data, dtype=float)
        if values.shape != (self.n,):
            self._reject("wrong joint count", f"{values.size} values for {self.n} joints")
            return
        if not np.isfinite(values).all():
            self._reject("non-finite value", f"{values.tolist()}")
            return
        if self.params.command_interface == "position":
            self._target = values
        else:
            self._held = values
        self.commands += 1
        if self.params.mode == "stepped":
            if self.commands == 1:
                self._idle.cancel()
            self._tick()

    def _reject(self, reason: str, detail: str) -> None:
        self.rejected[reason] += 1
        if self.rejected[reason] == 1 or self.rejected[reason] % 100 == 0:
            self._log.warning(
                f"rejected a command on {self.params.command_topic} ({reason}, "
                f"{self.rejected[reason]} so far): {detail}"
            )

    def _velocity(self) -> np.ndarray:
        """The velocity [rad/s] to hold for the coming period."""
        if self.params.command_interface == "velocity":
            return self._held
        u = (self._target - self._reached) / self.params.period_s
        self._reached = self._target.copy()
        return u

    def _tick(self) -> None:
        """Step the simulation one period and publish its state."""
        try:
            self.driver.write(self._velocity())
        except Exception as exc:  # noqa: BLE001 - the robot reports, it does not stop
            self._reject("driver error", f"{type(exc).__name__}: {exc}")
            return
        self._state = self.driver.read()
        muted = 0 <= self.params.mute_after <= self.commands
        if not muted:
            self._publish_state()

    def _publish_state(self) -> None:
        m = self._state
        msg = self.ros.sensor.JointState(name=list(self.joint_names))
        sec = math.floor(m.t_s)
        msg.header.stamp.sec = int(sec)
        msg.header.stamp.nanosec = min(int(round((m.t_s - sec) * 1e9)), 999_999_999)
        msg.position = [float(v) for v in m.q]
        msg.velocity = [float(v) for v in m.qd]
        msg.effort = [float(v) for v in m.torque]
        self._pub.publish(msg)

    def report(self) -> dict:
        """What was served: commands taken, rejected by reason, the last state."""
        return {
            "commands": self.commands,
            "rejected": dict(self.rejected),
            "t_s": float(self._state.t_s),
            "q": [float(v) for v in self._state.q],
            "qd": [float(v) for v in self._state.qd],
            "last_velocity": [float(v) for v in self._held],
        }

    def report_line(self) -> str:
        """One line: the commands taken and rejected."""
        return f"took {self.commands} commands; rejected {dict(self.rejected) or 'none'}"

    def write_report(self) -> None:
        """:meth:`report` as JSON to ``report_file`` (nothing when it is empty)."""
        if self.params.report_file:
            Path(self.params.report_file).write_text(json.dumps(self.report()) + "\n")
