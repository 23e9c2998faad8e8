"""dqcontrol over ROS 2: the control node drives a MuJoCo robot node through ros2_control's
topics (/joint_states in, Float64MultiArray velocity commands out), stepped in lockstep.

    python demos/ros2_bridge.py            # the path-following controller on the circle
    python demos/ros2_bridge.py --short    # a quick run (what CI executes)

Both nodes live in this process and talk over ROS 2 as separate processes would; DDS
discovery is kept on this host (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST unless set).
Against a real arm, run only the control node (``dqcontrol ros2 control``, docs/ros2.md).
"""

from __future__ import annotations

import argparse
import os
import threading

PERIOD_S = 0.01  # [s]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", action="store_true", help="quick run (for CI)")
    parser.add_argument("--viewer", action="store_true", help="no viewer here: RViz shows "
                        "the markers on /dqcontrol_control/markers and ~/target")  # fmt: skip
    parser.add_argument("--duration", type=float, default=2.0, help="T_tot [s] (default 2)")
    parser.add_argument("--controller", default="pf", help="a registry name (local, p10, pf)")
    args = parser.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

    from dqcontrol.model import LBR4P_Q0, load_lbr4p
    from dqcontrol.ros2 import ControlParams, SimParams
    from dqcontrol.ros2.control_node import ControlNode
    from dqcontrol.ros2.ros import require_ros
    from dqcontrol.ros2.sim_node import SimNode
    from dqcontrol.sim import MujocoDriver

    rclpy = require_ros().rclpy  # the [ros2] extra, or a sourced ROS 2 installation
    rclpy.init()
    executor = rclpy.executors.SingleThreadedExecutor()
    spinner = threading.Thread(target=executor.spin, daemon=True)
    try:
        # the robot: MuJoCo at rest at the start posture, behind /joint_states,
        # /robot_description and /forward_velocity_controller/commands
        robot = load_lbr4p()
        driver = MujocoDriver(robot, PERIOD_S)
        driver.reset(LBR4P_Q0)
        sim_params = SimParams.from_values({"mode": "stepped", "period_s": PERIOD_S})
        sim_node = rclpy.create_node("dqcontrol_sim")
        SimNode(sim_node, sim_params, robot, driver)

        # the controller: reads the robot from /robot_description, runs the circle
        params = ControlParams.from_values({
            "ee_frame": "lbr4p_flange", "controller": args.controller, "mode": "stepped",
            "period_s": PERIOD_S, "duration_s": 1.0 if args.short else args.duration,
            "exit_when_done": True,
        })  # fmt: skip
        control_node = rclpy.create_node("dqcontrol_control")
        control = ControlNode(control_node, params)

        executor.add_node(sim_node)
        executor.add_node(control_node)
        spinner.start()
        control.start()
        code = control.run()
        m = control.results[-1].metrics
        print(f"completed={m.completed}, samples={len(control.results[-1].log)}, "
              f"path deviation max {m.path_deviation_max_m * 1e3:.3f} mm")  # fmt: skip
        return code
    finally:
        executor.shutdown(timeout_sec=1.0)
        if spinner.is_alive():
            spinner.join()
        rclpy.try_shutdown()


if __name__ == "__main__":
    raise SystemExit(main())
