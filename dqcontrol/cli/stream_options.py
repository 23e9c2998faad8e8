"""The options of a streamed run (``--plan-period``, ``--jerk-limit``): the path-following
controller plans every ``T_p`` and its plans are streamed every ``--period`` (docs/theory.md
§12, docs/streaming.md)."""

from __future__ import annotations

import argparse

__all__ = [
    "add_stream_options",
    "check_stream_options",
    "measured_plan_period",
    "planner_acceleration",
    "stream_summary",
    "streamed_from_args",
]


def add_stream_options(group) -> None:
    """Add ``--plan-period`` and ``--jerk-limit`` to the argument ``group``."""
    from dqcontrol.cli.run_options import positive_float

    seconds = positive_float("s")

    def plan_period(text: str) -> float | str:
        return "auto" if text == "auto" else seconds(text)

    group.add_argument(
        "--plan-period",
        type=plan_period,
        default=None,
        metavar="T_P",
        help="plan every T_P [s] (a whole multiple of --period, or 'auto': twice the p99 of "
        "the measured step time, at least 5 ms) and stream the plans every --period: path "
        "following only (default: solve every period)",
    )
    group.add_argument(
        "--jerk-limit",
        type=positive_float("rad/s^3"),
        default=None,
        metavar="J",
        help="with --plan-period: joint jerk bound of the stream [rad/s^3] (default: the "
        "robot's, none when it gives none); --acceleration-limit then bounds the stream's "
        "acceleration and the planner plans with half of it",
    )


def check_stream_options(args: argparse.Namespace) -> None:
    """Parser error (exit 2) for a plan period shorter than ``--period`` or not a whole
    multiple of it, or a controller without a consistent plan."""
    from dqcontrol.controllers.path_following.controller import PathFollowingController
    from dqcontrol.registry import controller_spec

    parser = args._parser
    if args.plan_period is None:
        if args.jerk_limit is not None:
            parser.error("--jerk-limit bounds the stream of --plan-period: give --plan-period")
        return
    ratio = 1.0 if args.plan_period == "auto" else args.plan_period / args.period
    if round(ratio) < 1 or abs(ratio - round(ratio)) > 1e-9 * ratio:
        parser.error(
            f"--plan-period must be a whole multiple >= 1 of --period {args.period:g} s "
            f"(e.g. {max(round(ratio), 1) * args.period:g}), got {args.plan_period:g}"
        )
    for name in args.controllers:
        if not issubclass(controller_spec(name).cls, PathFollowingController):
            parser.error(
                f"--plan-period: {name} has no consistent plan to stream (its horizon is "
                "predicted from its previous plan); choose path following (--controllers pf)"
            )


def planner_acceleration(args: argparse.Namespace) -> float | None:
    """The planner's acceleration bound of a streamed run: half of ``--acceleration-limit``
    (the stream's), so that the plan's velocity steps fit their jerk-bounded blends
    (docs/theory.md §12.2); ``None``: the controller's own."""
    limit = args.acceleration_limit
    return None if limit is None else 0.5 * limit


def streamed_from_args(planner, args: argparse.Namespace):
    """``planner`` (built with ``period_s = --plan-period``) streamed at ``--period``."""
    from dqcontrol.streaming import streamed

    return streamed(
        planner, args.period, acceleration_max=args.acceleration_limit, jerk_max=args.jerk_limit
    )


def stream_summary(report: dict) -> str:
    """One line of a streamed run's ``meta["stream"]``: plans, step times, plan ages and,
    on the wall clock, late commands."""
    line = (
        f"plans every {1e3 * report['plan_period_s']:g} ms: {report['plans_used']} used, "
        f"{report['plans_refused']} refused; planner step median "
        f"{report['planner_step_median_ms']:.2f} ms, max {report['planner_step_max_ms']:.1f} "
        f"ms; streamer step median {report['streamer_step_median_us']:.1f} µs; plan age "
        f"median {report['plan_age_median_ms']:.0f} ms, max {report['plan_age_max_ms']:.0f} ms"
    )
    if "late_commands" in report:
        line += (
            f"; late commands {report['late_commands']} (lateness median "
            f"{report['lateness_median_ms']:.3f} ms, p99 {report['lateness_p99_ms']:.2f} ms, "
            f"max {report['lateness_max_ms']:.2f} ms)"
        )
    if report.get("playout"):
        line += f"; {report['playout']}"
    return line


#: Steps of a trial controller timed for ``--plan-period auto`` (the first few, which
#: iterate from rest, are left out).
AUTO_STEPS, AUTO_SKIP = 40, 10


def measured_plan_period(args: argparse.Namespace, robot, q0, velocity) -> float:
    """``--plan-period auto``: twice the p99 of the step time (at least 5 ms) of the first
    controller of the options, run at ``--period`` on the ideal kinematics from ``q0``, as
    a whole number of periods (:func:`~dqcontrol.streaming.planner.choose_plan_period`)."""
    import time

    from dqcontrol.cli.run_cmd import make_controller, make_trajectory
    from dqcontrol.streaming.planner import choose_plan_period

    trajectory, _ = make_trajectory(args.trajectory, args.duration)
    saved, args.plan_period = args.plan_period, None
    try:
        trial = make_controller(args.controllers[0], robot, trajectory, args, velocity)
    finally:
        args.plan_period = saved
    trial.reset(q0)
    q, times = q0.copy(), []
    for _ in range(AUTO_STEPS):
        start = time.perf_counter()
        q = q + args.period * trial.step(q).qd_command
        times.append(time.perf_counter() - start)
    return choose_plan_period(times[AUTO_SKIP:], args.period)
