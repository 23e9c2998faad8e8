"""``dqcontrol sim-server``: serve the MuJoCo simulation behind the joint-driver protocol on
a ZMQ socket (:mod:`dqcontrol.sim.bridge`), for a controller in another process."""

from __future__ import annotations

import argparse
import sys

from dqcontrol.cli.common import NO_BARS_HELP, add_progress_option
from dqcontrol.cli.robot_options import add_robot_options

__all__ = ["register"]

_DESCRIPTION = """\
Serve a robot in MuJoCo on a ZMQ socket (loopback by default). A client — the
dqcontrol.sim.bridge.BridgeDriver with run_loop, or any program that speaks the wire
format of docs/drivers.md — sends a reset, then one velocity command per control period;
the server steps the simulation one period per command and answers with the state. It
describes itself (robot, joints, period, drive, payload, versions) to a client that asks;
dqcontrol run --connect records that in the run log (meta "server"). Bad packets are
answered with an error and counted, never fatal. Ctrl-C stops it."""

_EPILOG = """\
examples:
  dqcontrol sim-server --port 5555
  dqcontrol sim-server --port 5555 --period 0.01 --motor torque --payload 3"""


def register(subparsers) -> None:
    """Add the ``sim-server`` subcommand."""
    p = subparsers.add_parser(
        "sim-server",
        help="serve the MuJoCo simulation to a controller in another process (ZMQ)",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_robot_options(p)
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=5555, help="TCP port (default 5555; 0: any)")
    p.add_argument("--period", type=float, default=0.05, help="control period T [s]")
    p.add_argument(
        "--motor", choices=("velocity", "torque"), default="velocity", help="joint drive"
    )
    p.add_argument("--payload", type=float, default=0.0, help="unknown payload [kg]")
    p.add_argument("--max-messages", type=int, default=None, help="stop after this many messages")
    add_progress_option(p, NO_BARS_HELP)
    p.set_defaults(func=_main, _parser=p)


def _main(args: argparse.Namespace) -> int:
    from dqcontrol.cli._extras import check_simulator
    from dqcontrol.cli.robot_options import RobotRequest, check_mujoco_meshes, load_robot
    from dqcontrol.sim import JointDriver, MujocoDriver, PayloadDriver
    from dqcontrol.sim.bridge import SimServer

    check_simulator("mujoco", "the simulation server")
    try:
        robot, _q0, _meta = load_robot(RobotRequest.from_args(args))
    except ValueError as exc:
        args._parser.error(str(exc))
    check_mujoco_meshes(args._parser, robot)
    if args.payload < 0.0:
        args._parser.error(f"--payload must be >= 0 kg, got {args.payload}")
    driver: JointDriver = MujocoDriver(robot, args.period, motor=args.motor)
    if args.payload > 0.0:
        driver = PayloadDriver(driver, args.payload)
    description = {"robot": robot.model.name, "robot_spec": args.robot, "ee_frame": robot.ee_frame}
    with SimServer(driver, f"tcp://{args.host}:{args.port}", description) as server:
        print(
            f"dqcontrol sim-server: {robot.model.name} ({len(driver.joint_names)} joints, "
            f"T = {args.period:g} s, {args.motor} drive) on {server.address}",
            flush=True,
        )
        try:
            server.serve(max_messages=args.max_messages)
        except KeyboardInterrupt:
            pass
        rejected = dict(server.rejected)
        print(f"served {server.served} messages; rejected {rejected or 'none'}", file=sys.stderr)
    return 0
