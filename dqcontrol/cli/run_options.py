"""The options of ``dqcontrol run``, in the groups of its ``--help``, and their types.

The robot options themselves are :mod:`dqcontrol.cli.robot_options`; the checks that need
the loaded robot (``--q0``'s length, ``--velocity-limits``, the collision model) are in
:mod:`dqcontrol.cli.run_cmd`.
"""

from __future__ import annotations

import argparse
import math

from dqcontrol.cli.common import add_out_option, add_progress_option
from dqcontrol.cli.robot_options import add_robot_options
from dqcontrol.cli.stream_options import add_stream_options
from dqcontrol.experiments.thesis import (
    THESIS_ACCELERATION_LIMIT,
    THESIS_HORIZON_S,
    THESIS_PERIOD_S,
)

__all__ = [
    "DEFAULT_CONTROLLERS",
    "PHYSICS_DT_S",
    "add_collision_options",
    "add_controller_options",
    "add_output_options",
    "add_run_options",
    "add_task_options",
    "float_list",
    "parse_controllers",
    "physics_steps_error",
    "positive_float",
]

#: The controllers of ``dqcontrol run`` without ``--controllers``.
DEFAULT_CONTROLLERS = ("local", "p10", "pf")
#: The physics step of the MuJoCo simulation [s]; a control period must be a multiple of it.
PHYSICS_DT_S = 0.001


def physics_steps_error(option: str, period_s: float) -> str | None:
    """The message for a control period given as ``option`` that is not a whole number of
    MuJoCo's physics steps, or ``None`` when it is one."""
    steps = round(period_s / PHYSICS_DT_S)
    if steps >= 1 and abs(period_s - steps * PHYSICS_DT_S) <= 1e-9:
        return None
    return (
        f"{option}: with --simulator mujoco, T must be a whole number of {PHYSICS_DT_S:g} s "
        f"physics steps (e.g. 0.001, 0.01, 0.05), got {period_s:g}"
    )


# ---------------------------------------------------------------------- option types
def positive_float(unit: str):
    """The argparse type of a finite number > 0 in ``unit`` (named in its error messages)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number [{unit}], got {text!r}") from None
        if not (math.isfinite(value) and value > 0.0):
            raise argparse.ArgumentTypeError(f"must be finite and > 0 [{unit}], got {text!r}")
        return value

    return parse


def float_list(text: str) -> tuple[float, ...]:
    """``"0.1, -0.2,0.3"`` → ``(0.1, -0.2, 0.3)``: finite numbers, at least one; argparse
    error otherwise."""
    try:
        values = tuple(float(v) for v in text.replace(" ", "").split(",") if v)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated numbers, got {text!r}"
        ) from None
    if not values or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected comma-separated finite numbers, got {text!r}")
    return values


def parse_controllers(text: str) -> tuple[str, ...]:
    """``"local,p10,path-following"`` → ``("local", "p10", "pf")``: the registry's canonical
    names, each once; argparse error (listing the known names) for an unknown one."""
    from dqcontrol.errors import ParameterError
    from dqcontrol.registry import controller_spec

    names: list[str] = []
    for raw in text.split(","):
        if not raw.strip():
            continue
        try:
            name = controller_spec(raw).name
        except ParameterError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        if name not in names:
            names.append(name)
    if not names:
        raise argparse.ArgumentTypeError("give at least one controller, e.g. local,p10")
    return tuple(names)


# ---------------------------------------------------------------------- the groups
def add_run_options(parser: argparse.ArgumentParser) -> None:
    """Add every option of ``dqcontrol run`` to ``parser``, group by group."""
    add_task_options(parser)
    add_controller_options(parser)
    add_collision_options(parser)
    add_output_options(parser)


def add_task_options(parser: argparse.ArgumentParser) -> None:
    """Add the group "robot and task": the robot options, ``--q0``, ``--trajectory`` and
    ``--duration``."""
    g = parser.add_argument_group("robot and task")
    add_robot_options(g)
    g.add_argument(
        "--q0",
        type=float_list,
        metavar="Q1,...,QN",
        help="initial joint angles [rad], e.g. --q0=-0.2,0.5,... (with '=' when the first is "
        "negative; default: the robot's start posture; for a URDF, the middle of its limits)",
    )
    g.add_argument(
        "--trajectory",
        choices=("circle", "sinusoid"),
        default="circle",
        help="the thesis's circle (R = 0.1 m, default) or sinusoid (A = 0.1 m)",
    )
    g.add_argument(
        "--duration",
        type=positive_float("s"),
        default=2.0,
        metavar="T_TOT",
        help="nominal duration T_tot of the trajectory [s] (default: 2)",
    )


def add_controller_options(parser: argparse.ArgumentParser) -> None:
    """Add the group "controllers": ``--controllers``, ``--period``, ``--gain``, ``--horizon``
    and the joint bounds."""
    g = parser.add_argument_group("controllers")
    g.add_argument(
        "--controllers",
        type=parse_controllers,
        default=DEFAULT_CONTROLLERS,
        metavar="LIST",
        help=f"comma-separated controllers (default: {','.join(DEFAULT_CONTROLLERS)}; see below)",
    )
    g.add_argument(
        "--period",
        type=positive_float("s"),
        default=THESIS_PERIOD_S,
        metavar="T",
        help="control period T [s] (default: 0.05; 0.001 runs the 1 kHz controller)",
    )
    g.add_argument(
        "--gain",
        type=positive_float("1/s"),
        metavar="K",
        help="task gain K [1/s] of every controller that has one (default: 10; noscale: its "
        "stable default; the path-following controller has none)",
    )
    g.add_argument(
        "--horizon",
        type=positive_float("s"),
        default=THESIS_HORIZON_S,
        metavar="TAU_P",
        help="prediction horizon tau_p of the predictive and path-following controllers [s] "
        "(default: 1)",
    )
    g.add_argument(
        "--velocity-limits",
        metavar="LIMITS",
        help="joint velocity bounds [rad/s]: 'thesis' (pi*[1,1,1,1,2.5,2.5,2.5], default for "
        "the LBR4p with all 7 joints and no --limits), 'urdf' (the robot's: the URDF's, or "
        "the --limits profile's; default otherwise) or comma-separated values",
    )
    g.add_argument(
        "--acceleration-limit",
        type=positive_float("rad/s^2"),
        default=None,
        metavar="A",
        help="joint acceleration bound [rad/s^2] of every controller (default: the --limits "
        "profile's where it gives one, else each controller's own: "
        f"{THESIS_ACCELERATION_LIMIT:g} for the thesis's controllers, the dynamics-aware bound "
        "from the robot's inertia and effort limits for path following, capped by the "
        "profile's)",
    )
    add_stream_options(g)


def add_collision_options(parser: argparse.ArgumentParser) -> None:
    """Add the group of ``--obstacle``, ``--self-collision`` and ``--safety-distance``."""
    g = parser.add_argument_group(
        "obstacles and self-collision (every QP controller keeps its distance, docs/theory.md "
        "section 10)"
    )
    g.add_argument(
        "--obstacle",
        action="append",
        default=[],
        metavar="SHAPE:VALUES",
        help="an obstacle fixed in the world, every value in metres (repeatable): "
        "sphere:X,Y,Z,R; box:X,Y,Z,SX,SY,SZ (centre and side lengths, axis-aligned); "
        "capsule:X,Y,Z,R,L and cylinder:X,Y,Z,R,L (centre, radius, length, vertical axis); "
        "plane:NX,NY,NZ,D (the solid n.x <= D below the plane, n pointing into free space: "
        "plane:0,0,1,0.45 is a table top 0.45 m high)",
    )
    g.add_argument(
        "--self-collision",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="also keep the robot's own links apart (default: off)",
    )
    g.add_argument(
        "--safety-distance",
        type=positive_float("m"),
        default=0.02,
        metavar="D_S",
        help="distance kept from obstacles and between links [m] (default: 0.02; pairs "
        "closer than 0.1 m are constrained)",
    )


def add_output_options(parser: argparse.ArgumentParser) -> None:
    """Add the group "simulation, viewer and output": the simulator or ``--connect``, the live
    viewer, ``--out`` and how the results are written."""
    g = parser.add_argument_group("simulation, viewer and output")
    g.add_argument(
        "--simulator",
        choices=("mujoco", "kinematic"),
        default="mujoco",
        help="MuJoCo physics with torque-limited velocity servos (default) or the ideal "
        "kinematic loop",
    )
    _add_connect_options(g)
    g.add_argument(
        "--viewer",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="show the robot live in the browser (Meshcat; the URL is printed). Default: off",
    )
    g.add_argument(
        "--speed",
        type=positive_float("x real time"),
        default=1.0,
        help="speed of the live viewer and of the replays (1 = real time, default)",
    )
    g.add_argument(
        "--hold",
        type=float,
        metavar="SECONDS",
        help="with --viewer: keep the viewer open this long after the runs, replaying the "
        "last one (default: until Ctrl-C when run from a terminal, else not at all)",
    )
    add_out_option(g, "results", "results folder")
    g.add_argument("--svg", action="store_true", help="write the figures as SVG instead of PNG")
    g.add_argument(
        "--short",
        action="store_true",
        help="fast mode for CI: low-resolution figures and replays, no progress bars",
    )
    add_progress_option(g)


def _add_connect_options(g) -> None:
    """Add ``--connect`` and the wall-clock options of a run against a sim-server to the
    argument group ``g``."""
    g.add_argument(
        "--connect",
        metavar="ADDRESS",
        default=None,
        help="run against a `dqcontrol sim-server` in another process (tcp://HOST:PORT or, "
        "for periods of a few ms, udp://HOST:PORT, as the server was started) instead of "
        "simulating here; --period must be the server's",
    )
    g.add_argument(
        "--realtime",
        action="store_true",
        help="with --connect: keep the wall clock (one period per period; a missed deadline "
        "is counted and the loop goes on in the present period; a sample later than "
        "--max-lateness stops along the path and holds) instead of stepping as fast as "
        "possible",
    )
    g.add_argument(
        "--max-lateness",
        metavar="SECONDS",
        type=positive_float("s"),
        default=None,
        help="with --realtime: stop along the path when a sample ends more than this after "
        "its deadline (default: five periods)",
    )
    g.add_argument(
        "--rt-priority",
        metavar="N",
        type=int,
        default=None,
        help="with --realtime: run the loop in Linux's real-time scheduling class at "
        "priority N (1-99; needs CAP_SYS_NICE or an rtprio limit, ulimit -r). Default: the "
        "ordinary scheduler",
    )
