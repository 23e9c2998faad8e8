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
from a saved run's ``meta``, are shared with ``dqcontrol view``. The options are declared in
:mod:`dqcontrol.cli.run_options` (the robot's in :mod:`dqcontrol.cli.robot_options`); the
progress bars, the metrics table and the result files are :mod:`dqcontrol.cli.run_output`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dqcontrol.cli.robot_options import (
    RobotRequest,
    check_mujoco_meshes,
    load_robot,
    robot_label,
)
from dqcontrol.cli.run_options import add_run_options, float_list, physics_steps_error
from dqcontrol.cli.run_output import (
    TABLE_LEGEND,
    collision_report,
    hold_viewer,
    loaded_result,
    metrics_table,
    progress_bar,
    progress_callback,
    show_progress,
    with_contacts,
    write_results,
)
from dqcontrol.cli.stream_options import (
    check_stream_options,
    measured_plan_period,
    planner_acceleration,
    stream_summary,
    streamed_from_args,
)
from dqcontrol.experiments.thesis import THESIS_VELOCITY_LIMITS
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
MuJoCo, the thesis's velocity bounds |qd| <= pi*[1,1,1,1,2.5,2.5,2.5] rad/s for every
controller, |qdd| <= 10 rad/s^2 for the thesis's controllers and the dynamics-aware
acceleration bound for path following."""

_EPILOG = f"""\
controllers (comma-separated, any case):
{CONTROLLER_HELP}

examples:
  dqcontrol run
  dqcontrol run --viewer --speed 0.5
  dqcontrol run --trajectory sinusoid --duration 4 --controllers local,p6,p10,pf
  dqcontrol run --period 0.001                      the 1 kHz controller
  dqcontrol run --robot panda --simulator kinematic
  dqcontrol run --robot panda --limits franka_panda --period 0.001 --controllers pf
  dqcontrol run --robot my_arm.urdf --ee-frame tool0 --q0=0,-0.5,0,-1.5,0,1,0 \
      --package-dir ~/ws/src
  dqcontrol run --robot erd:ur5 --ee-frame tool0 --q0=0,-1.2,1.5,-1.9,-1.57,0
  dqcontrol run --robot erd:panda --ee-frame panda_hand --lock panda_finger_joint1=0 \
      --lock panda_finger_joint2=0 --tool 0,0,0.1
  dqcontrol run --controllers pf --obstacle sphere:0.49,-0.39,0.70,0.03
  dqcontrol run --obstacle plane:0,0,1,0.45 --obstacle box:0.3,-0.5,0.4,0.2,0.1,0.3 \
      --self-collision"""


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
    add_run_options(p)
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
    """The controller ``name`` (see :func:`~dqcontrol.cli.run_options.parse_controllers`)
    with the options' settings: each controller takes those of the bounds, gain and horizon
    it has (:func:`dqcontrol.registry.build_controller`)."""
    from dqcontrol.registry import build_controller

    extra = {}
    collision = getattr(args, "_collision", None)
    if collision is not None:
        from dqcontrol.controllers.limits.collision import CollisionLimit

        extra["extra_limits"] = (CollisionLimit(collision, safety_distance_m=args.safety_distance),)
    shared = {
        "velocity_limits": velocity_limits,
        "gain_per_s": args.gain,
        "horizon_s": args.horizon,
    }
    if args.acceleration_limit is not None:  # otherwise each controller's own default
        shared["acceleration_limit"] = args.acceleration_limit
    if args.simulator == "mujoco":  # a controller that models the servos gets their lag
        from dqcontrol.sim.mujoco_sim import SERVO_TIME_CONSTANT_S

        shared["servo_time_constant_s"] = SERVO_TIME_CONSTANT_S
    plan_period = getattr(args, "plan_period", None)
    if plan_period is None:
        return build_controller(name, robot, trajectory, args.period, shared=shared, **extra)
    if args.acceleration_limit is not None:
        shared["acceleration_limit"] = planner_acceleration(args)
    planner = build_controller(name, robot, trajectory, plan_period, shared=shared, **extra)
    return streamed_from_args(planner, args)


def run_connected(args, controller, q0, meta: dict, on_progress, log_file=None):
    """One run against the sim-server at ``args.connect`` (:class:`~dqcontrol.sim.bridge.
    BridgeDriver` and :func:`~dqcontrol.sim.loop.run_loop`), its log streamed to
    ``log_file`` (``None``: kept in memory)."""
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
            realtime=args.realtime, log_file=log_file, max_lateness_s=args.max_lateness,
            realtime_priority=args.rt_priority,
        )  # fmt: skip
    finally:
        driver.close()


# ---------------------------------------------------------------------- the options' checks
def _check_wall_clock_options(args) -> None:
    """Parser error (exit 2) for a wall-clock option without ``--realtime`` (or
    ``--realtime`` without ``--connect``), or a real-time priority this process may not
    take."""
    from dqcontrol.errors import ParameterError
    from dqcontrol.sim.bridge_transport import parse_address
    from dqcontrol.sim.priority import check_priority

    parser = args._parser
    if args.connect is not None:
        try:
            parse_address(args.connect)
        except ParameterError as exc:
            parser.error(f"--connect: {exc}")
    if args.realtime and not args.connect:
        parser.error("--realtime keeps the wall clock against a sim-server: give --connect")
    for given, option in (
        (args.max_lateness, "--max-lateness"),
        (args.rt_priority, "--rt-priority"),
    ):
        if given is not None and not args.realtime:
            parser.error(f"{option} applies to a wall-clock run: give --realtime")
    try:
        check_priority(args.rt_priority)
    except ParameterError as exc:
        parser.error(f"--rt-priority: {exc}")


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
        spec = "thesis" if thesis_arm and robot.limit_profile == "urdf" else "urdf"
    _note_period(args, robot)
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
            values = float_list(spec)
        except argparse.ArgumentTypeError as exc:
            parser.error(f"--velocity-limits: 'thesis', 'urdf' or numbers: {exc}")
        if len(values) not in (1, n) or min(values) <= 0:
            parser.error(f"--velocity-limits: give 1 or {n} values > 0 [rad/s], got {list(values)}")
        velocity = np.broadcast_to(np.array(values, dtype=float), (n,)).copy()
    if args.period > args.duration:
        parser.error(f"--period T = {args.period:g} s is longer than T_tot = {args.duration:g} s")
    if args.simulator == "mujoco" and not args.connect:
        check_mujoco_meshes(parser, robot)
    if args.simulator == "mujoco":
        message = physics_steps_error("--period", args.period)
        if message is not None:
            parser.error(message)
    if args.hold is not None and not (args.hold >= 0):
        parser.error(f"--hold must be >= 0 seconds, got {args.hold}")
    args._collision = _collision_model(args, robot, q0)
    _check_wall_clock_options(args)
    check_stream_options(args)
    if args.plan_period == "auto":
        args.plan_period = measured_plan_period(args, robot, q0, velocity)
        print(f"dqcontrol run: --plan-period auto: {args.plan_period:g} s", file=sys.stderr)
    return robot, q0, robot_meta, velocity


def _note_period(args, robot) -> None:
    """A note on stderr when the limit profile's robot does not accept ``--period``."""
    if args.limits is None:
        return
    from dqcontrol.model.limit_profile import load_profile

    profile = load_profile(args.limits)
    if not profile.accepts_period(args.period):
        accepted = ", ".join(f"{p:g}" for p in profile.periods_s)
        print(
            f"dqcontrol run: note: the robot of limit profile {profile.name!r} accepts control "
            f"periods of {accepted} s, not --period {args.period:g}",
            file=sys.stderr,
        )


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


# ---------------------------------------------------------------------- the command
def _main(args: argparse.Namespace) -> int:
    """Run each controller of the options, print the metrics table and write the results.

    Returns:
        The exit code: 0, or 1 when a run did not complete the trajectory.
    """
    from dqcontrol.cli._extras import check_simulator

    if not args.connect:  # with --connect the server simulates
        check_simulator(args.simulator)
    robot, q0, robot_meta, velocity = _check_options(args)
    robot.check_q(q0, "--q0")
    name = robot_label(robot_meta)
    out = Path(args.out) / f"{name}_{args.trajectory}_T{args.duration:g}s_{args.simulator}"
    viewer = _open_viewer(args, robot, q0)
    try:
        runs = [
            _run_controller(label, args, robot, q0, robot_meta, velocity, viewer, out)
            for label in args.controllers
        ]
        runs = with_contacts(runs, robot, args._collision)
        written = _write_results(runs, robot, out, args, name)
        _print_summary(args, name, robot, runs)
        print(f"wrote {len(written)} file{'s' if len(written) != 1 else ''} to {out}/")
        _replay_last(viewer, runs, args)
    finally:
        if viewer is not None:
            viewer.close()
    return _exit_code(runs)


def _write_results(runs, robot, out: Path, args, name: str) -> list[Path]:
    """:func:`~dqcontrol.cli.run_output.write_results`, a failed write (full disk, a folder
    not writable) reported as a :class:`~dqcontrol.errors.DQControlError` (exit 1)."""
    from dqcontrol.errors import DQControlError

    try:
        return write_results(runs, robot, out, args, name)
    except OSError as exc:
        for label, result, _ in runs:
            if result.note:
                print(f"{label}: {result.note}", file=sys.stderr)
        raise DQControlError(
            f"cannot write the results to {out}/: {exc} (free disk space or choose a "
            "writable --out)"
        ) from None


def _open_viewer(args: argparse.Namespace, robot, q0):
    """The live Meshcat viewer at ``q0`` with the obstacles, or ``None`` without ``--viewer``."""
    from dqcontrol.viz.meshcat_viewer import MeshcatViewer

    collision = args._collision
    obstacles = collision.obstacles if collision is not None else ()
    viewer = MeshcatViewer(robot, q=q0) if args.viewer else None
    if viewer is not None and obstacles:
        viewer.show_obstacles(obstacles)
    return viewer


def _run_controller(
    label: str, args, robot, q0, robot_meta: dict, velocity, viewer, out: Path
) -> tuple:
    """Build the controller ``label`` on a fresh trajectory and run it with a progress bar,
    its log streamed to ``out/<label>.mcap`` (then loaded back, decimated if long:
    :func:`~dqcontrol.cli.run_output.loaded_result`); its run's note, if any, goes to stderr.

    Returns:
        ``(label, RunResult, the controller's anchored trajectory)``.
    """
    trajectory, traj_meta = make_trajectory(args.trajectory, args.duration)
    controller = make_controller(label, robot, trajectory, args, velocity)
    meta = _run_meta(args, label, controller, q0, velocity, {**robot_meta, **traj_meta})
    bar = progress_bar(f"{label:>12}", args.duration, show_progress(args))
    on_progress = progress_callback(bar)
    try:
        result = _simulate(args, controller, q0, meta, viewer, on_progress, out / f"{label}.mcap")
    finally:
        bar.close()
    if "stream" in result.log.meta:
        print(f"{label}: {stream_summary(result.log.meta['stream'])}")
    if result.note:
        print(f"{label}: {result.note}", file=sys.stderr)
    return label, result, controller.trajectory


def _acceleration_meta(controller, args) -> float | str | None:
    """The acceleration bound the controller runs with: ``"dynamics"`` (the dynamics-aware
    one), the ``--acceleration-limit`` given, or the controller's own constant [rad/s²]."""
    import numpy as np

    if getattr(controller, "dynamic_acceleration", False):
        return "dynamics"
    if args.acceleration_limit is not None:
        return float(args.acceleration_limit)
    for name in ("a_const", "a_max"):
        value = getattr(controller, name, None)
        if value is not None:
            return float(np.max(value))
    return None


def _run_meta(args, label: str, controller, q0, velocity, task_meta: dict) -> dict:
    """The ``meta`` saved with a run: ``task_meta`` (the robot's and the trajectory's), the
    label, the start, the bounds, the gain and horizon, and the collision options."""
    meta = {
        **task_meta,
        "label": label,
        "q0": [float(v) for v in q0],
        "velocity_limits": [float(v) for v in velocity],
        "acceleration_limit": _acceleration_meta(controller, args),
        "gain_per_s": getattr(controller, "gain_per_s", None),
        "horizon_s": getattr(controller, "horizon_s", None),
        "command": "dqcontrol run",
    }
    if args._collision is not None:
        meta["obstacles"] = list(args.obstacle)
        meta["self_collision"] = bool(args.self_collision)
        meta["safety_distance_m"] = args.safety_distance
    return meta


def _simulate(args, controller, q0, meta: dict, viewer, on_progress, log_file: Path):
    """One run of ``controller``, its log streamed to ``log_file``: against the sim-server
    with ``--connect``, else in MuJoCo (the viewer follows it live) or the kinematic loop
    (the viewer plays it afterwards). Every run ends with the controller's stop along the
    path (logged, flagged ``stopping``), as a real arm's run would."""
    from dqcontrol.sim import run_kinematic, run_mujoco

    collision = args._collision
    if args.connect:
        return loaded_result(run_connected(args, controller, q0, meta, on_progress, log_file))
    if args.simulator == "mujoco":
        on_sample = viewer.follow(controller, speed=args.speed) if viewer else None
        return loaded_result(run_mujoco(
            controller, q0, meta=meta, on_sample=on_sample, on_progress=on_progress,
            obstacles=collision.obstacles if collision is not None else (), log_file=log_file,
            brake=True,
        ))  # fmt: skip
    result = loaded_result(
        run_kinematic(
            controller, q0, meta=meta, on_progress=on_progress, log_file=log_file, brake=True
        )
    )
    if viewer is not None:
        viewer.play(
            result.log,
            speed=args.speed,
            path_points=controller.trajectory.path_positions(1000),
        )
    return result


def _print_summary(args: argparse.Namespace, name: str, robot, runs: list) -> None:
    """Print the task, the metrics table and its legend, and with obstacles or
    self-collision one line per run on distances and contacts."""
    print(
        f"{name} on the {args.trajectory}, T_tot = {args.duration:g} s, T = "
        f"{args.period:g} s, {args.simulator}"
    )
    print(metrics_table([(label, result.metrics) for label, result, _ in runs]))
    print(TABLE_LEGEND)
    collision = args._collision
    if collision is not None:
        print(
            f"collision: {collision.num_pairs} pairs, safety distance "
            f"{1e3 * args.safety_distance:g} mm (contacts: the run's states in MuJoCo "
            "with the obstacles)"
        )
        for label, result, _ in runs:
            print("  " + collision_report(label, result))


def _replay_last(viewer, runs: list, args: argparse.Namespace) -> None:
    """Replay the last run that has samples in the live viewer and keep it open ``--hold``."""
    drawable = [(label, r.log, traj) for label, r, traj in runs if len(r.log)]
    if viewer is not None and drawable:
        label, log, traj = drawable[-1]
        viewer.clear_trace()
        viewer.show_path(traj.path_positions(1000))
        viewer.set_animation(log, speed=args.speed)
        hold_viewer(viewer, args.hold)


def _exit_code(runs: list) -> int:
    """0 when every run completed the trajectory, else 1 (and, on stderr, for each
    incomplete run how far it got and why it stopped)."""
    incomplete = [
        (label, r, traj) for label, r, traj in runs if r.interrupted or not r.metrics.completed
    ]
    for label, r, traj in incomplete:
        print(f"dqcontrol run: {label} did not complete the trajectory: {_stop(r, traj)}",
              file=sys.stderr)  # fmt: skip
    return 1 if incomplete else 0


def _stop(result, trajectory) -> str:
    """Where an incomplete run stopped: its phase against ``T_tot``, and the loop's note or
    what a phase at rest means."""
    reached = float(result.log.sigma[-1]) if len(result.log) else 0.0
    where = f"the phase reached {reached:.3g} s of T_tot = {trajectory.duration:g} s"
    if result.interrupted:
        return f"{where} ({result.note})" if result.note else where
    if len(result.log) and float(result.log.s[-1]) < 1e-3:
        return f"{where}, where it stopped (s = 0): the path ahead is out of reach or blocked"
    return f"{where} when the run's time limit came"
