"""``dqcontrol run``: run controllers on a trajectory, print their metrics, write the results.

The default is the README's first command: the thesis's KUKA LBR4p on the circle with
``T_tot = 2 s``, the local, the predictive (p = 10) and the path-following controllers
simulated in MuJoCo with the thesis's bounds (:mod:`dqcontrol.experiments.thesis`).
Controllers are built by name through :mod:`dqcontrol.registry`; trajectories are saved and
rebuilt through their own metadata (:meth:`~dqcontrol.trajectories.Trajectory.to_metadata`).
Everything lands in ``OUT/<robot>_<trajectory>_T<T_tot>s_<simulator>/``:
per controller its run (``<ctrl>.npz`` + ``.json``), its figures (``<ctrl>_<figure>.png``)
and its replay (``<ctrl>_replay.html``), and ``comparison.png`` for two or more controllers.
The figures and replays need the ``viz`` extra; without it the runs are saved, the metrics
printed, and a note on stderr says what was not written. ``--simulator mujoco`` needs the
``sim`` extra.

The helpers that turn options into a trajectory and controllers, and rebuild the trajectory
from a saved run's ``meta``, are shared with ``dqcontrol view``; the robot options are
:mod:`dqcontrol.cli.robot_options`.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from dqcontrol.cli.common import add_out_option, add_progress_option
from dqcontrol.cli.robot_options import (
    RobotRequest,
    add_robot_options,
    load_robot,
    robot_label,
)
from dqcontrol.experiments.thesis import (
    THESIS_ACCELERATION_LIMIT,
    THESIS_HORIZON_S,
    THESIS_PERIOD_S,
    THESIS_VELOCITY_LIMITS,
)
from dqcontrol.registry import CONTROLLER_HELP

__all__ = ["register"]

_DESCRIPTION = """\
Run one or more controllers on a trajectory, print a table of their metrics, and write to
OUT/<robot>_<trajectory>_T<T_tot>s_<simulator>/: each run (.npz + .json, reload with
'dqcontrol view'), its figures (path in 2-D and 3-D, translation and rotation against the
phase, joint velocities, angles and torques, s(t) and sigma(t)), a self-contained HTML
replay that plays in any browser, and a figure comparing the controllers. The figures and
replays need the [viz] extra (pip install 'dqcontrol[viz]'), MuJoCo the [sim] extra; without
[viz] the runs and metrics are still written.

Defaults: the LBR4p on the circle (R = 0.1 m) with T_tot = 2 s, the local, the predictive
(p = 10) and the path-following (p = 10) controllers, T = 0.05 s, tau_p = 1 s, K = 10 1/s,
MuJoCo, the thesis's bounds |qd| <= pi*[1,1,1,1,2.5,2.5,2.5] rad/s and |qdd| <= 10 rad/s^2
for every controller."""

_EPILOG = f"""\
controllers (comma-separated, any case):
{CONTROLLER_HELP}

examples:
  dqcontrol run
  dqcontrol run --viewer --speed 0.5
  dqcontrol run --trajectory sinusoid --duration 4 --controllers local,p6,p10,pf
  dqcontrol run --period 0.001                      the 1 kHz controller
  dqcontrol run --robot panda --simulator kinematic
  dqcontrol run --robot my_arm.urdf --ee-frame tool0 --q0=0,-0.5,0,-1.5,0,1,0 \
      --package-dir ~/ws/src
  dqcontrol run --robot erd:ur5 --ee-frame tool0 --q0=0,-1.2,1.5,-1.9,-1.57,0
  dqcontrol run --robot erd:panda --ee-frame panda_hand --lock panda_finger_joint1=0 \
      --lock panda_finger_joint2=0 --tool 0,0,0.1
  dqcontrol run --controllers pf --obstacle sphere:0.49,-0.39,0.70,0.03
  dqcontrol run --obstacle plane:0,0,1,0.45 --obstacle box:0.3,-0.5,0.4,0.2,0.1,0.3 \
      --self-collision"""

#: The physics step of the MuJoCo simulation [s]; ``T`` must be a multiple of it.
PHYSICS_DT_S = 0.001
#: The controllers of ``dqcontrol run`` without ``--controllers``.
DEFAULT_CONTROLLERS = ("local", "p10", "pf")


# ---------------------------------------------------------------------- option types
def _positive_float(unit: str):
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number [{unit}], got {text!r}") from None
        if not (math.isfinite(value) and value > 0.0):
            raise argparse.ArgumentTypeError(f"must be finite and > 0 [{unit}], got {text!r}")
        return value

    return parse


def _float_list(text: str) -> tuple[float, ...]:
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


# ---------------------------------------------------------------------- the parser
def register(subparsers) -> None:
    """Add the ``run`` subcommand."""
    p = subparsers.add_parser(
        "run",
        help="run controllers (default: LBR4p, circle, local vs p = 10 vs path following, "
        "MuJoCo) and write metrics, figures and replays",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    g = p.add_argument_group("robot and task")
    add_robot_options(g)
    g.add_argument(
        "--q0",
        type=_float_list,
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
        type=_positive_float("s"),
        default=2.0,
        metavar="T_TOT",
        help="nominal duration T_tot of the trajectory [s] (default: 2)",
    )
    g = p.add_argument_group("controllers")
    g.add_argument(
        "--controllers",
        type=parse_controllers,
        default=DEFAULT_CONTROLLERS,
        metavar="LIST",
        help=f"comma-separated controllers (default: {','.join(DEFAULT_CONTROLLERS)}; see below)",
    )
    g.add_argument(
        "--period",
        type=_positive_float("s"),
        default=THESIS_PERIOD_S,
        metavar="T",
        help="control period T [s] (default: 0.05; 0.001 runs the 1 kHz controller)",
    )
    g.add_argument(
        "--gain",
        type=_positive_float("1/s"),
        metavar="K",
        help="task gain K [1/s] of every controller that has one (default: 10; noscale: its "
        "stable default; the path-following controller has none)",
    )
    g.add_argument(
        "--horizon",
        type=_positive_float("s"),
        default=THESIS_HORIZON_S,
        metavar="TAU_P",
        help="prediction horizon tau_p of the predictive and path-following controllers [s] "
        "(default: 1)",
    )
    g.add_argument(
        "--velocity-limits",
        metavar="LIMITS",
        help="joint velocity bounds [rad/s]: 'thesis' (pi*[1,1,1,1,2.5,2.5,2.5], default for "
        "the LBR4p with all 7 joints), 'urdf' (default otherwise) or comma-separated values",
    )
    g.add_argument(
        "--acceleration-limit",
        type=_positive_float("rad/s^2"),
        default=THESIS_ACCELERATION_LIMIT,
        metavar="A",
        help="joint acceleration bound [rad/s^2] of every controller (default: 10)",
    )
    g = p.add_argument_group(
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
        type=_positive_float("m"),
        default=0.02,
        metavar="D_S",
        help="distance kept from obstacles and between links [m] (default: 0.02; pairs "
        "closer than 0.1 m are constrained)",
    )
    g = p.add_argument_group("simulation, viewer and output")
    g.add_argument(
        "--simulator",
        choices=("mujoco", "kinematic"),
        default="mujoco",
        help="MuJoCo physics with torque-limited velocity servos (default) or the ideal "
        "kinematic loop",
    )
    g.add_argument(
        "--connect",
        metavar="ADDRESS",
        default=None,
        help="run against a `dqcontrol sim-server` in another process (tcp://127.0.0.1:PORT, "
        "loopback only) instead of simulating here; --period must be the server's",
    )
    g.add_argument(
        "--realtime",
        action="store_true",
        help="with --connect: keep the wall clock (one period per period; the watchdog "
        "brakes and holds on a missed deadline) instead of stepping as fast as possible",
    )
    g.add_argument(
        "--viewer",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="show the robot live in the browser (Meshcat; the URL is printed). Default: off",
    )
    g.add_argument(
        "--speed",
        type=_positive_float("x real time"),
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
    p.set_defaults(func=_main, _parser=p)


# ---------------------------------------------------------------------- tasks
def make_trajectory(kind: str, duration_s: float):
    """The thesis's circle or sinusoid, and the ``meta`` that rebuilds it (its own
    :meth:`~dqcontrol.trajectories.Trajectory.to_metadata`)."""
    from dqcontrol.trajectories import trajectory_from_metadata

    traj = trajectory_from_metadata({"trajectory": kind, "duration_s": duration_s})
    return traj, traj.to_metadata()


def trajectory_from_meta(meta: dict, log):
    """The anchored trajectory of a saved run, or ``None`` if its meta does not say."""
    from dqcontrol.errors import ParameterError
    from dqcontrol.trajectories import trajectory_from_metadata

    if len(log) == 0:
        return None
    try:
        traj = trajectory_from_metadata(meta)
    except ParameterError:
        return None
    if traj.reference is not None:
        return traj
    return traj.anchored_at(log.target[0])  # target(0) is the anchor pose x0


def make_controller(name: str, robot, trajectory, args, velocity_limits):
    """The controller ``name`` (see :func:`parse_controllers`) with the options' settings:
    each controller takes those of the bounds, gain and horizon it has
    (:func:`dqcontrol.registry.build_controller`)."""
    from dqcontrol.registry import build_controller

    extra = {}
    collision = getattr(args, "_collision", None)
    if collision is not None:
        from dqcontrol.controllers.limits.collision import CollisionLimit

        extra["extra_limits"] = (CollisionLimit(collision, safety_distance_m=args.safety_distance),)
    shared = {
        "velocity_limits": velocity_limits,
        "acceleration_limit": args.acceleration_limit,
        "gain_per_s": args.gain,
        "horizon_s": args.horizon,
    }
    if args.simulator == "mujoco":  # a controller that models the servos gets their lag
        from dqcontrol.sim.mujoco_sim import SERVO_TIME_CONSTANT_S

        shared["servo_time_constant_s"] = SERVO_TIME_CONSTANT_S
    return build_controller(name, robot, trajectory, args.period, shared=shared, **extra)


def run_connected(args, controller, q0, meta: dict, on_progress):
    """One run against the sim-server at ``args.connect`` (:class:`~dqcontrol.sim.bridge.
    BridgeDriver` and :func:`~dqcontrol.sim.loop.run_loop`)."""
    from dqcontrol.errors import ParameterError
    from dqcontrol.sim.bridge import BridgeDriver
    from dqcontrol.sim.loop import run_loop

    driver = BridgeDriver(args.connect)
    try:
        if abs(driver.period_s - args.period) > 1e-12:
            raise ParameterError(
                f"--period {args.period:g} s differs from the sim-server's period "
                f"{driver.period_s:g} s: pass --period {driver.period_s:g}"
            )
        return run_loop(
            controller, driver, q0=q0, meta=meta, on_progress=on_progress,
            realtime=args.realtime,
        )  # fmt: skip
    finally:
        driver.close()


# ---------------------------------------------------------------------- output helpers
def progress_bar(label: str, total: float, enabled: bool):
    """A tqdm bar over the phase σ [s]; shown only after one second, and on a terminal."""
    from tqdm import tqdm

    return tqdm(
        total=round(total, 9),
        desc=label,
        unit="s",
        delay=1.0,
        leave=False,
        disable=None if enabled else True,
        bar_format="{desc}: {percentage:3.0f}%|{bar}| σ {n:.2f}/{total:.2f} s "
        "[{elapsed}<{remaining}]",
    )


def progress_callback(bar):
    """The loops' ``on_progress(σ_next, T_tot)`` callback that advances ``bar`` to σ [s]."""
    total = bar.total or 0.0

    def report(sigma_next: float, _duration: float) -> None:
        target = min(float(sigma_next), total)
        if target > bar.n:
            bar.update(target - bar.n)

    return report


_COLUMNS = (
    ("controller", "{:<12}", None),
    ("done", "{:>4}", lambda m: "yes" if m.completed else "NO"),
    ("t_exec", "{:>6}", lambda m: _fmt(m.execution_time_s, "{:.3f}")),
    ("e_mean", "{:>8}", lambda m: _fmt(m.e_mean, "{:.5f}")),
    ("e_max", "{:>8}", lambda m: _fmt(m.e_max, "{:.5f}")),
    ("dev_mm", "{:>6}", lambda m: _fmt(1e3 * m.path_deviation_max_m, "{:.2f}")),
    ("rot_deg", "{:>7}", lambda m: _fmt(math.degrees(m.rotation_error_max_rad), "{:.2f}")),
    ("u_mean", "{:>6}", lambda m: _fmt(m.u_mean_rad_s, "{:.3f}")),
    ("s_mean", "{:>6}", lambda m: _fmt(m.s_mean, "{:.3f}")),
    ("tau_Nm", "{:>6}", lambda m: _fmt(m.torque_peak_nm, "{:.1f}")),
    (
        "viol",
        "{:>7}",
        lambda m: f"{m.position_violations}/{m.velocity_violations}/{m.acceleration_violations}",
    ),
    ("fb", "{:>3}", lambda m: str(m.fallbacks)),
    ("step_ms", "{:>7}", lambda m: _fmt(1e3 * m.step_time_median_s, "{:.2f}")),
)
#: What the columns mean (printed under the table).
TABLE_LEGEND = (
    "t_exec: execution time [s]; e: ‖x_d - x‖; dev_mm: max path deviation [mm]; rot_deg: max "
    "rotation error [deg];\nu_mean [rad/s]; tau_Nm: peak torque; viol: samples outside the "
    "position/velocity/acceleration bounds;\nfb: QP fallbacks; step_ms: median control step [ms]"
)


def _fmt(value: float, spec: str) -> str:
    return "-" if value is None or not math.isfinite(value) else spec.format(value)


def metrics_table(rows: list[tuple[str, object]]) -> str:
    """A plain-text table of ``(label, Metrics)`` rows (violations: position/velocity/accel.)."""
    head = " ".join(fmt.format(name) for name, fmt, _ in _COLUMNS)
    lines = [head, "-" * len(head)]
    for label, metrics in rows:
        cells = [_COLUMNS[0][1].format(label[:12])]
        cells += [fmt.format(get(metrics)) for _, fmt, get in _COLUMNS[1:]]
        lines.append(" ".join(cells))
    return "\n".join(lines)


def hold_viewer(viewer, hold: float | None) -> None:
    """Keep a live viewer open ``hold`` seconds (``None``: until Ctrl-C on a terminal)."""
    if hold is None:
        if not sys.stdin or not sys.stdin.isatty():
            return
        print(f"Meshcat viewer still open at {viewer.url} (replaying); Ctrl-C to quit", flush=True)
        hold = math.inf
    if hold <= 0:
        return
    deadline = time.monotonic() + hold
    try:
        while time.monotonic() < deadline:
            time.sleep(min(0.2, max(deadline - time.monotonic(), 0.0)))
    except KeyboardInterrupt:
        pass


# ---------------------------------------------------------------------- the command
def _check_options(args) -> tuple:
    """Build robot, q0, bounds from the options; parser error (exit 2) when one is wrong."""
    import numpy as np

    parser = args._parser
    try:
        robot, q0, robot_meta = load_robot(RobotRequest.from_args(args))
    except ValueError as exc:
        parser.error(str(exc))
    n = robot.nq
    if args.q0 is not None:
        if len(args.q0) != n:
            parser.error(
                f"--q0: the robot has {n} joints {robot.joint_names}, got {len(args.q0)} values"
            )
        q0 = np.array(args.q0, dtype=float)
    spec = args.velocity_limits
    if spec is None:
        thesis_arm = robot_meta["robot"] == "lbr4p" and n == len(THESIS_VELOCITY_LIMITS)
        spec = "thesis" if thesis_arm else "urdf"
    if spec == "thesis":
        if n != len(THESIS_VELOCITY_LIMITS):
            parser.error(
                f"--velocity-limits thesis has 7 values; this robot has {n} joints (use 'urdf' "
                "or give values)"
            )
        velocity = np.array(THESIS_VELOCITY_LIMITS)
    elif spec == "urdf":
        velocity = np.array(robot.limits.qd_max, dtype=float)
        if not np.all(np.isfinite(velocity) & (velocity > 0)):
            parser.error(
                f"--velocity-limits urdf: the URDF's velocity limits {velocity.tolist()} are "
                "not all > 0; give values"
            )
    else:
        try:
            values = _float_list(spec)
        except argparse.ArgumentTypeError as exc:
            parser.error(f"--velocity-limits: 'thesis', 'urdf' or numbers: {exc}")
        if len(values) not in (1, n) or min(values) <= 0:
            parser.error(f"--velocity-limits: give 1 or {n} values > 0 [rad/s], got {list(values)}")
        velocity = np.broadcast_to(np.array(values, dtype=float), (n,)).copy()
    if args.period > args.duration:
        parser.error(f"--period T = {args.period:g} s is longer than T_tot = {args.duration:g} s")
    if args.simulator == "mujoco":
        steps = round(args.period / PHYSICS_DT_S)
        if steps < 1 or abs(args.period - steps * PHYSICS_DT_S) > 1e-9:
            parser.error(
                f"--period: with --simulator mujoco, T must be a whole number of "
                f"{PHYSICS_DT_S:g} s physics steps (e.g. 0.001, 0.01, 0.05), got {args.period:g}"
            )
    if args.hold is not None and not (args.hold >= 0):
        parser.error(f"--hold must be >= 0 seconds, got {args.hold}")
    args._collision = _collision_model(args, robot, q0)
    return robot, q0, robot_meta, velocity


def _collision_model(args, robot, q0):
    """The collision model of ``--obstacle``/``--self-collision`` (``None`` without them);
    parser error (exit 2) for a bad obstacle, a bad safety distance or a controller that
    takes no limits."""
    from dqcontrol.errors import ParameterError
    from dqcontrol.model.collision import CollisionModel, parse_obstacle
    from dqcontrol.registry import controller_spec

    parser = args._parser
    if not args.obstacle and not args.self_collision:
        return None
    obstacles = []
    for k, text in enumerate(args.obstacle):
        try:
            obstacles.append(parse_obstacle(text, name=f"obstacle{k + 1}"))
        except ParameterError as exc:
            parser.error(f"--obstacle: {exc}")
    if not args.safety_distance < 0.1:
        parser.error(
            f"--safety-distance must be < 0.1 m (the influence distance), got "
            f"{args.safety_distance:g}"
        )
    limitless = [c for c in args.controllers if not controller_spec(c).qp]
    if limitless:
        parser.error(
            f"--obstacle/--self-collision: {', '.join(limitless)} takes no limits; choose QP "
            "controllers (e.g. --controllers local,p10,pf)"
        )
    try:
        model = CollisionModel(robot, obstacles, self_collision=args.self_collision)
    except ParameterError as exc:
        parser.error(f"--obstacle/--self-collision: {exc}")
    start = model.min_distance(q0)
    if start < args.safety_distance:
        print(
            f"dqcontrol run: the start configuration is {1e3 * start:.1f} mm from contact, "
            f"inside the safety distance {1e3 * args.safety_distance:g} mm",
            file=sys.stderr,
        )
    return model


def collision_report(label: str, robot, collision, qs) -> str:
    """One line per run: the smallest distance over the run and the contacts of its
    configurations in the MuJoCo model with the obstacles."""
    import numpy as np

    from dqcontrol.sim.mjcf_builder import replay_contacts

    qs = np.atleast_2d(qs)
    if qs.shape[0] == 0:
        return f"{label}: no samples"
    closest = min(collision.min_distance(q) for q in qs)
    contacts = replay_contacts(robot, collision.obstacles, qs)
    return (
        f"{label}: min distance {1e3 * closest:.1f} mm; contacts robot-obstacle "
        f"{contacts.obstacle}, self {contacts.self_contact}, deepest "
        f"{1e3 * contacts.deepest_m:.1f} mm"
    )


def _main(args: argparse.Namespace) -> int:
    from dqcontrol.cli._extras import check_simulator

    if not args.connect:  # with --connect the server simulates
        check_simulator(args.simulator)
    robot, q0, robot_meta, velocity = _check_options(args)

    from dqcontrol.sim import run_kinematic, run_mujoco
    from dqcontrol.viz.meshcat_viewer import MeshcatViewer

    robot.check_q(q0, "--q0")
    name = robot_label(robot_meta)
    stem = f"{name}_{args.trajectory}_T{args.duration:g}s_{args.simulator}"
    out = Path(args.out) / stem
    fmt = "svg" if args.svg else "png"
    dpi = 60.0 if args.short else 110.0
    fps = 10.0 if args.short else 30.0
    progress = args.progress and not args.short

    collision = args._collision
    obstacles = collision.obstacles if collision is not None else ()
    viewer = MeshcatViewer(robot, q=q0) if args.viewer else None
    if viewer is not None and obstacles:
        viewer.show_obstacles(obstacles)
    try:
        runs = []  # (label, result, anchored trajectory)
        for label in args.controllers:
            trajectory, traj_meta = make_trajectory(args.trajectory, args.duration)
            controller = make_controller(label, robot, trajectory, args, velocity)
            meta = {
                **robot_meta,
                **traj_meta,
                "label": label,
                "q0": [float(v) for v in q0],
                "velocity_limits": [float(v) for v in velocity],
                "acceleration_limit": args.acceleration_limit,
                "gain_per_s": getattr(controller, "gain_per_s", None),
                "horizon_s": getattr(controller, "horizon_s", None),
                "command": "dqcontrol run",
            }
            if collision is not None:
                meta["obstacles"] = list(args.obstacle)
                meta["self_collision"] = bool(args.self_collision)
                meta["safety_distance_m"] = args.safety_distance
            bar = progress_bar(f"{label:>12}", args.duration, progress)
            on_progress = progress_callback(bar)
            try:
                if args.connect:
                    result = run_connected(args, controller, q0, meta, on_progress)
                elif args.simulator == "mujoco":
                    on_sample = viewer.follow(controller, speed=args.speed) if viewer else None
                    result = run_mujoco(
                        controller, q0, meta=meta, on_sample=on_sample, on_progress=on_progress,
                        obstacles=collision.obstacles if collision is not None else (),
                    )  # fmt: skip
                else:
                    result = run_kinematic(controller, q0, meta=meta, on_progress=on_progress)
                    if viewer is not None:
                        viewer.play(
                            result.log,
                            speed=args.speed,
                            path_points=controller.trajectory.path_positions(1000),
                        )
            finally:
                bar.close()
            if result.note:
                print(f"{label}: {result.note}", file=sys.stderr)
            runs.append((label, result, controller.trajectory))

        written = _write_results(runs, robot, out, args, fmt, dpi, fps, progress, name)
        print(
            f"{name} on the {args.trajectory}, T_tot = {args.duration:g} s, T = "
            f"{args.period:g} s, {args.simulator}"
        )
        print(metrics_table([(label, result.metrics) for label, result, _ in runs]))
        print(TABLE_LEGEND)
        if collision is not None:
            print(
                f"collision: {collision.num_pairs} pairs, safety distance "
                f"{1e3 * args.safety_distance:g} mm (contacts: the run's states in MuJoCo "
                "with the obstacles)"
            )
            for label, result, _ in runs:
                print("  " + collision_report(label, robot, collision, result.log.q))
        print(f"wrote {len(written)} file{'s' if len(written) != 1 else ''} to {out}/")
        drawable = [(label, r.log, traj) for label, r, traj in runs if len(r.log)]
        if viewer is not None and drawable:
            label, log, traj = drawable[-1]
            viewer.clear_trace()
            viewer.show_path(traj.path_positions(1000))
            viewer.set_animation(log, speed=args.speed)
            hold_viewer(viewer, args.hold)
    finally:
        if viewer is not None:
            viewer.close()
    rows = [(label, result) for label, result, _ in runs]
    incomplete = [label for label, r in rows if r.interrupted or not r.metrics.completed]
    if incomplete:
        print(
            f"dqcontrol run: {', '.join(incomplete)} did not complete the trajectory",
            file=sys.stderr,
        )
        return 1
    return 0


def _write_results(runs, robot, out, args, fmt, dpi, fps, progress, name) -> list[Path]:
    """Save each run, its figures and replay, and the comparison figure (with a progress bar)."""
    from tqdm import tqdm

    from dqcontrol.extras import has_extra
    from dqcontrol.runs.storage import save_run

    drawable = [(label, r, traj) for label, r, traj in runs if len(r.log)]
    if not has_extra("viz"):  # the runs alone, and say what is missing
        print(
            "dqcontrol run: figures and replays not written: they need the [viz] extra "
            "(pip install 'dqcontrol[viz]')",
            file=sys.stderr,
        )
        return [path for label, result, _ in drawable for path in save_run(result, out, label)]

    from dqcontrol.viz.figures import plot_comparison, plot_run
    from dqcontrol.viz.meshcat_viewer import export_replay_html

    steps = 3 * len(drawable) + (len(drawable) >= 2)
    written: list[Path] = []
    with tqdm(
        total=steps,
        desc="writing results",
        unit="file",
        delay=1.0,
        leave=False,
        disable=None if progress else True,
    ) as bar:
        for label, result, traj in drawable:
            written += save_run(result, out, label)
            bar.update()
            written += plot_run(result.log, out, name=label, trajectory=traj, fmt=fmt, dpi=dpi)
            bar.update()
            html = out / f"{label}_replay.html"
            points = traj.path_positions(1000)
            collision = getattr(args, "_collision", None)
            written.append(
                export_replay_html(
                    robot,
                    result.log,
                    html,
                    path_points=points,
                    fps=fps,
                    speed=args.speed,
                    obstacles=collision.obstacles if collision is not None else (),
                )
            )
            bar.update()
        if len(drawable) >= 2:
            title = (
                f"{name}, {args.trajectory}, T_tot = {args.duration:g} s, T = {args.period:g} s, "
                f"{args.simulator}"
            )
            logs = {label: r.log for label, r, _ in drawable}
            written.append(
                plot_comparison(
                    logs,
                    out / f"comparison.{fmt}",
                    trajectory=drawable[-1][2],
                    dpi=dpi,
                    title=title,
                )
            )
            bar.update()
    return written
