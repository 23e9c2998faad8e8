"""dqcontrol on ROS 2: a control node that a ros2_control arm plugs into, and a MuJoCo robot
node that behaves like one (docs/ros2.md).

- :class:`~dqcontrol.ros2.control_node.ControlNode` (``dqcontrol ros2 control``): reads
  ``/joint_states``, runs a controller of the registry
  (:func:`~dqcontrol.registry.build_controller`) on the task (the thesis's circle or
  sinusoid, or a ``nav_msgs/Path`` on ``~/path``), and publishes ``Float64MultiArray``
  commands for a forward command controller, ``~/status`` and RViz markers;
- :class:`~dqcontrol.ros2.sim_node.SimNode` (``dqcontrol ros2 sim``): the robot in MuJoCo
  behind ``/joint_states``, ``robot_description`` and a forward velocity (or position)
  command topic, on the wall clock or stepped one period per command.

Nothing here imports ROS 2 at import time: the modules that need rclpy and the message
packages import them through :func:`dqcontrol.ros2.ros.require_ros` when a node is built,
which raises :class:`~dqcontrol.errors.MissingExtraError` naming the ``[ros2]`` extra.
The checks of what arrives (:mod:`~dqcontrol.ros2.joint_states`), the parameters
(:mod:`~dqcontrol.ros2.params`) and the path task (:mod:`~dqcontrol.ros2.paths`) are plain
Python.
"""

from dqcontrol.ros2.joint_states import JointStateCheck, Rejected
from dqcontrol.ros2.params import ControlParams, SimParams
from dqcontrol.ros2.paths import trajectory_from_poses

__all__ = [
    "ControlParams",
    "JointStateCheck",
    "Rejected",
    "SimParams",
    "trajectory_from_poses",
]
