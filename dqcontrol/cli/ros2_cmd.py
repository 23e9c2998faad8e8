"""``dqcontrol ros2 control`` and ``dqcontrol ros2 sim``: the ROS 2 nodes (docs/ros2.md).

Their settings are ROS 2 parameters, given after ``--ros-args`` as every ROS 2 node takes
them (``-p name:=value``, ``--params-file``, remappings). Without rclpy (the ``[ros2]``
extra, or a sourced ROS 2 installation) each says so in one line, exit code 1; a bad
parameter is one line naming it, exit code 1.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["register"]

_DESCRIPTION = """\
dqcontrol as ROS 2 nodes. 'control' runs a controller of the registry against a
ros2_control arm: /joint_states in, Float64MultiArray commands out for a forward command
controller, the task by parameter (circle, sinusoid) or as a nav_msgs/Path on ~/path,
~/status and RViz markers out, ~/stop to stop. 'sim' is a MuJoCo robot behind the same
topics. Parameters follow --ros-args (docs/ros2.md lists them)."""

_EPILOG = """\
examples:
  dqcontrol ros2 sim --ros-args -p mode:=wall -p period_s:=0.01
  dqcontrol ros2 control --ros-args -p ee_frame:=lbr4p_flange -p controller:=pf \\
      -p command_topic:=/forward_velocity_controller/commands"""


def register(subparsers) -> None:
    """Add the ``ros2`` subcommand group (``control``, ``sim``)."""
    p = subparsers.add_parser(
        "ros2",
        help="dqcontrol as ROS 2 nodes: the control node, a MuJoCo robot node",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.set_defaults(func=lambda _args: _no_node(p))
    nodes = p.add_subparsers(dest="node", metavar="NODE")
    for name, func, text in (
        ("control", _control, "run a controller against a ros2_control arm"),
        ("sim", _sim, "a MuJoCo robot behind ros2_control's topics"),
    ):
        q = nodes.add_parser(name, help=text, description=text + " (docs/ros2.md)")
        q.add_argument(
            "--ros-args",
            dest="ros_args",
            nargs=argparse.REMAINDER,
            default=[],
            help="ROS 2 arguments: -p NAME:=VALUE, --params-file FILE, remappings",
        )
        q.set_defaults(func=func)


def _no_node(parser: argparse.ArgumentParser) -> int:
    parser.print_help(sys.stderr)
    return 2


def _check_extra() -> None:
    from dqcontrol.extras import EXTRAS, available, missing_extra
    from dqcontrol.ros2.ros import PURPOSE

    for module in EXTRAS["ros2"]:
        if not available(module):
            raise missing_extra(module, extra="ros2", purpose=PURPOSE)


def _control(args: argparse.Namespace) -> int:
    _check_extra()
    from dqcontrol.ros2.control_node import ControlNode
    from dqcontrol.ros2.params import ControlParams
    from dqcontrol.ros2.session import ros_node, spin_in_background

    with ros_node("dqcontrol_control", args.ros_args, ControlParams) as (node, params):
        with spin_in_background(node):
            control = ControlNode(node, params)
            try:
                control.start()
                return control.run()
            except KeyboardInterrupt:
                return 130


def _sim(args: argparse.Namespace) -> int:
    _check_extra()
    from dqcontrol.ros2.params import SimParams
    from dqcontrol.ros2.session import ros_node

    with ros_node("dqcontrol_sim", args.ros_args, SimParams) as (node, params):
        sim = _sim_node(node, params)
        executor = sim.ros.rclpy.executors.SingleThreadedExecutor(context=node.context)
        executor.add_node(node)
        try:
            while node.context.ok():  # short waits: Ctrl-C and SIGTERM get through
                executor.spin_once(timeout_sec=0.1)
        except KeyboardInterrupt:
            pass
        finally:
            sim.write_report()
            executor.shutdown(timeout_sec=1.0)
        print(f"dqcontrol ros2 sim: {sim.report_line()}", file=sys.stderr)
    return 0


def _sim_node(node, params):
    """The simulated robot of ``params`` at rest at its start posture."""
    import numpy as np

    from dqcontrol.cli._extras import check_simulator
    from dqcontrol.cli.robot_options import RobotRequest, load_robot
    from dqcontrol.errors import ParameterError
    from dqcontrol.ros2.sim_node import SimNode
    from dqcontrol.sim import MujocoDriver

    check_simulator("mujoco", "dqcontrol ros2 sim")
    request = RobotRequest(
        spec=params.robot,
        ee_frame=params.ee_frame or None,
        locked_joints=tuple(params.locks().items()),
    )
    try:
        robot, q0, _meta = load_robot(request)
    except ValueError as exc:
        raise ParameterError(f"parameter 'robot': {exc}") from None
    if params.q0:
        if len(params.q0) != robot.nq:
            raise ParameterError(
                f"parameter 'q0' must have {robot.nq} joint positions [rad] "
                f"({', '.join(robot.joint_names)}), got {len(params.q0)}"
            )
        q0 = np.array(params.q0)
    driver = MujocoDriver(robot, params.period_s, motor=params.motor)
    driver.reset(q0)
    return SimNode(node, params, robot, driver)
