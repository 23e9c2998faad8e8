"""A ROS 2 joint driver: joint states in, joint-velocity commands out (rclpy).

NOT TESTED IN CI: ROS 2 (rclpy, sensor_msgs, std_msgs) does not install from the Python
package registries this project's CI uses. Run it in a sourced ROS 2 workspace next to a
robot (or a simulator) that publishes ``sensor_msgs/JointState`` and takes velocity
commands as ``std_msgs/Float64MultiArray`` — the interface of ros2_control's
``JointGroupVelocityController``::

    python demos/ros2_bridge.py --states /joint_states \\
        --commands /velocity_controller/commands --controller pf --duration 4

The controller runs in :func:`dqcontrol.sim.loop.run_loop` on the wall clock exactly as it
does against MuJoCo; the loop maps the driver's joint order to the model's by name (a
mismatch is refused before any command), and its watchdog brakes within the acceleration
limit and holds when the joint states stop arriving.
"""

from __future__ import annotations

import argparse
import threading
import time

import numpy as np

from dqcontrol.model.library import load_lbr4p
from dqcontrol.registry import build_controller
from dqcontrol.sim.loop import run_loop
from dqcontrol.sim.mujoco_sim import Measurement
from dqcontrol.trajectories import Circle


class Ros2VelocityDriver:
    """A :class:`~dqcontrol.sim.driver.JointDriver` over two ROS 2 topics.

    Args:
        node: an ``rclpy`` node (spun in a background thread by :func:`main`).
        joint_names: the joints to command, in the order the command topic expects.
        states_topic: ``sensor_msgs/JointState`` topic.
        commands_topic: ``std_msgs/Float64MultiArray`` topic of velocity commands [rad/s].
    """

    def __init__(self, node, joint_names, states_topic: str, commands_topic: str) -> None:
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray

        self._msg_type = Float64MultiArray
        self._names = tuple(joint_names)
        self._lock = threading.Lock()
        self._latest: Measurement | None = None
        self._pub = node.create_publisher(Float64MultiArray, commands_topic, 10)
        node.create_subscription(JointState, states_topic, self._on_state, 10)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self._names

    def _on_state(self, msg) -> None:
        index = {name: k for k, name in enumerate(msg.name)}
        if not all(name in index for name in self._names):
            return  # a message about other joints
        order = [index[name] for name in self._names]
        qd = np.asarray(msg.velocity, dtype=float)[order] if msg.velocity else np.zeros(len(order))
        effort = np.asarray(msg.effort, dtype=float)[order] if msg.effort else None
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        torque = effort if effort is not None else np.full(len(order), np.nan)
        with self._lock:
            self._latest = Measurement(
                stamp, np.asarray(msg.position, dtype=float)[order], qd, torque, np.abs(torque)
            )

    def read(self) -> Measurement:
        """The latest joint state (waits up to 5 s for the first one)."""
        deadline = time.monotonic() + 5.0
        while True:
            with self._lock:
                if self._latest is not None:
                    return self._latest
            if time.monotonic() > deadline:
                raise TimeoutError("no sensor_msgs/JointState with the model's joints in 5 s")
            time.sleep(0.01)

    def write(self, qd_command: np.ndarray) -> None:
        self._pub.publish(self._msg_type(data=[float(v) for v in qd_command]))

    def hold(self) -> None:
        self.write(np.zeros(len(self._names)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", default="/joint_states", help="JointState topic")
    parser.add_argument("--commands", default="/velocity_controller/commands")
    parser.add_argument("--controller", default="pf", help="a registry name (local, p10, pf)")
    parser.add_argument("--duration", type=float, default=4.0, help="T_tot of the circle [s]")
    parser.add_argument("--period", type=float, default=0.01, help="control period [s]")
    args = parser.parse_args()

    import rclpy

    rclpy.init()
    node = rclpy.create_node("dqcontrol_bridge")
    spinner = threading.Thread(target=rclpy.spin, args=(node,), daemon=True)
    spinner.start()
    robot = load_lbr4p()  # replace with RobotModel.from_urdf(<your URDF>, <flange frame>)
    driver = Ros2VelocityDriver(node, robot.joint_names, args.states, args.commands)
    controller = build_controller(args.controller, robot, Circle(args.duration), args.period)
    try:
        result = run_loop(controller, driver, realtime=True)
        print(result.metrics)
    finally:
        driver.hold()
        node.destroy_node()
        rclpy.shutdown()


if __name__ == "__main__":
    main()
