"""The control node's robot: from a URDF file, or from the ``robot_description`` topic as
robot_state_publisher serves it (``std_msgs/String``, transient local, reliable)."""

from __future__ import annotations

import threading
from typing import Any

import pinocchio as pin

from dqcontrol.errors import DQControlError
from dqcontrol.model.robot import RobotModel
from dqcontrol.ros2.params import ControlParams

__all__ = ["base_frame", "description_qos", "load_control_robot"]


def description_qos(ros: Any) -> Any:
    """The QoS of ``robot_description``: reliable, transient local, depth 1 (a late joiner
    gets the last description)."""
    qos = ros.rclpy.qos
    return qos.QoSProfile(
        depth=1,
        reliability=qos.ReliabilityPolicy.RELIABLE,
        durability=qos.DurabilityPolicy.TRANSIENT_LOCAL,
    )


def _description_text(node: Any, ros: Any, topic: str, wait_s: float) -> str:
    got: list[str] = []
    arrived = threading.Event()

    def take(msg: Any) -> None:
        got.append(msg.data)
        arrived.set()

    sub = node.create_subscription(ros.std.String, topic, take, description_qos(ros))
    try:
        if not arrived.wait(wait_s):
            raise DQControlError(
                f"no robot description on {topic} in {wait_s:g} s (is robot_state_publisher "
                "running? or give the parameter robot_description_file)"
            )
    finally:
        node.destroy_subscription(sub)
    return got[0]


def load_control_robot(node: Any, ros: Any, params: ControlParams) -> RobotModel:
    """The robot of ``params``: the URDF file, or the text on the description topic (the
    node must be spinning in another thread), with its end-effector frame and locks.

    Raises:
        DQControlError: no description in ``wait_s``; a URDF or frame error (its message
            lists what exists).
    """
    if params.robot_description_file:
        urdf = params.robot_description_file
    else:
        topic = params.robot_description_topic
        urdf = _description_text(node, ros, topic, params.wait_s)
    return RobotModel.from_urdf(urdf, params.ee_frame, locked_joints=params.locks() or None)


def base_frame(robot: RobotModel) -> str:
    """The robot's base frame: the URDF's root link (the frame of the path's poses)."""
    for frame in robot.model.frames:
        if frame.type == pin.FrameType.BODY:
            return str(frame.name)
    return "world"  # pragma: no cover - a URDF has a root link
