"""The one door to ROS 2: rclpy and the message packages, or the ``[ros2]`` extra's message.

With the ``[ros2]`` extra the wheels of the ROS 2 packages provide them; in a shell where a
ROS 2 installation is sourced, its own rclpy and messages are found first (docs/ros2.md).
"""

from __future__ import annotations

from types import SimpleNamespace

from dqcontrol.extras import EXTRAS, require

__all__ = ["PURPOSE", "require_ros"]

#: What needs ROS 2, for the missing-extra message.
PURPOSE = "ROS 2 support (dqcontrol ros2)"


def require_ros() -> SimpleNamespace:
    """The modules the nodes use: rclpy and the messages, as attributes of one namespace.

    Returns:
        ``rclpy`` (with ``rclpy.executors``, ``rclpy.qos``, ``rclpy.signals`` imported)
        and the ``msg``/``srv`` modules: ``sensor``, ``std``, ``std_srvs``,
        ``geometry``, ``nav``, ``visualization``, ``diagnostic``.

    Raises:
        MissingExtraError: one of them does not import; the message names the ``[ros2]``
            extra and how to install it.
    """
    for module in (*EXTRAS["ros2"], "rclpy.executors", "rclpy.qos", "rclpy.signals"):
        require(module, extra="ros2", purpose=PURPOSE)
    return SimpleNamespace(
        rclpy=require("rclpy", extra="ros2", purpose=PURPOSE),
        sensor=require("sensor_msgs.msg", extra="ros2", purpose=PURPOSE),
        std=require("std_msgs.msg", extra="ros2", purpose=PURPOSE),
        std_srvs=require("std_srvs.srv", extra="ros2", purpose=PURPOSE),
        geometry=require("geometry_msgs.msg", extra="ros2", purpose=PURPOSE),
        nav=require("nav_msgs.msg", extra="ros2", purpose=PURPOSE),
        visualization=require("visualization_msgs.msg", extra="ros2", purpose=PURPOSE),
        diagnostic=require("diagnostic_msgs.msg", extra="ros2", purpose=PURPOSE),
    )
