"""``dqcontrol sim-server``: serve the MuJoCo simulation behind the joint-driver protocol on
a ZMQ or UDP socket (:mod:`dqcontrol.sim.bridge`), for a controller in another process."""

from __future__ import annotations

import argparse
import sys

from dqcontrol.cli.common import NO_BARS_HELP, add_progress_option
from dqcontrol.cli.robot_options import add_robot_options

__all__ = ["register"]

_DESCRIPTION = """\
Serve a robot in MuJoCo on a socket (loopback by default): ZMQ over TCP, or UDP
datagrams with --transport udp (no I/O threads: about 0.1 ms less per exchange, the
transport for periods of a few milliseconds; a datagram may be lost, as on a real arm's
link). A client — the dqcontrol.sim.bridge.BridgeDriver with run_loop, or any program
that speaks the wire format of docs/drivers.md — sends a reset, then one velocity command
per control period; the server steps the simulation one period per command and answers
with the state. It
describes itself (robot, joints, period, drive, payload, versions) to a client that asks;
dqcontrol run --connect records that in the run log (meta "server"). Bad packets are
answered with an error and counted, never fatal. Ctrl-C stops it.

Like a real arm, it checks every command: with --limits PROFILE the velocity,
acceleration and jerk of the commands (the arm at rest at each reset) and the position of
the simulated arm against the profile; without, the velocity against the URDF's limits.
The first violation fires the reflex: the arm is stopped, the command answered with an
ERROR naming the violation (kind, joint, value, limit), and every later motion command
refused until the next RESET."""

_EPILOG = """\
examples:
  dqcontrol sim-server --port 5555
  dqcontrol sim-server --port 5555 --period 0.01 --motor torque --payload 3
  dqcontrol sim-server --port 5555 --period 0.001 --transport udp
  dqcontrol sim-server --robot panda --limits franka_panda --period 0.001"""


def register(subparsers) -> None:
    """Add the ``sim-server`` subcommand."""
    p = subparsers.add_parser(
        "sim-server",
        help="serve the MuJoCo simulation to a controller in another process (ZMQ or UDP)",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_robot_options(p)
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=5555, help="port (default 5555; 0: any free one)")
    p.add_argument(
        "--transport",
        choices=("tcp", "udp"),
        default="tcp",
        help="tcp: ZMQ over TCP (default); udp: datagrams, the fast one (a client connects "
        "to udp://HOST:PORT)",
    )
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
    from dqcontrol.sim.reflexes import Reflexes

    check_simulator("mujoco", "the simulation server")
    try:
        robot, _q0, _meta = load_robot(RobotRequest.from_args(args))
    except ValueError as exc:
        args._parser.error(str(exc))
    check_mujoco_meshes(args._parser, robot)
    if args.payload < 0.0:
        args._parser.error(f"--payload must be >= 0 kg, got {args.payload}")
    _check_period(args)
    driver: JointDriver = MujocoDriver(robot, args.period, motor=args.motor)
    if args.payload > 0.0:
        driver = PayloadDriver(driver, args.payload)
    description = {"robot": robot.model.name, "robot_spec": args.robot, "ee_frame": robot.ee_frame}
    reflexes = Reflexes.of_robot(
        robot, driver.joint_names, args.period, velocity_only=args.limits is None
    )
    address = f"{args.transport}://{args.host}:{args.port}"
    with SimServer(driver, address, description, reflexes) as server:
        print(
            f"dqcontrol sim-server: {robot.model.name} ({len(driver.joint_names)} joints, "
            f"T = {args.period:g} s, {args.motor} drive, reflexes: {reflexes.profile} "
            f"limits) on {server.address}",
            flush=True,
        )
        try:
            server.serve(max_messages=args.max_messages)
        except KeyboardInterrupt:
            pass
        rejected = dict(server.rejected)
        print(f"served {server.served} messages; rejected {rejected or 'none'}", file=sys.stderr)
    return 0


def _check_period(args: argparse.Namespace) -> None:
    """A parser error (exit 2) when the profile's robot does not accept ``--period``."""
    if args.limits is None:
        return
    from dqcontrol.model.limit_profile import load_profile

    profile = load_profile(args.limits)  # loaded (and checked) with the robot already
    if not profile.accepts_period(args.period):
        accepted = ", ".join(f"{p:g}" for p in profile.periods_s)
        args._parser.error(
            f"--period {args.period:g}: the robot of limit profile {profile.name!r} accepts "
            f"control periods of {accepted} s"
        )
