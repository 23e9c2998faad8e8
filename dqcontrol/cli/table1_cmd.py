"""``dqcontrol table1``: run the thesis's Table 1 grid and write results/table1.md/.csv."""

from __future__ import annotations

import argparse
import shlex
import sys

from dqcontrol.cli.common import add_out_option, add_progress_option
from dqcontrol.cli.run_options import physics_steps_error, positive_float

__all__ = ["register"]

_DESCRIPTION = """\
Reproduce the thesis's Table 1: the circle at T_tot = 8, 4, 2, 1 s and the sinusoid at
16, 8, 4, 2 s, each with the local method and the predictive method at p = 6 and p = 10;
T = 0.05 s, tau_p = 1 s, the thesis's bounds (|qd| <= pi*[1,1,1,1,2.5,2.5,2.5] rad/s,
|qdd| <= 10 rad/s^2), start configuration LBR4P_Q0, the library's gains (K = 10 1/s).
Beside them, the path-following controller (rows 'path-following'; p = 10 intervals, the
same T, tau_p and velocity bounds, otherwise its defaults: its dynamics-aware acceleration
limit, which behind MuJoCo's 5 ms servos at T = 0.05 s is 5 rad/s^2 on this arm, the
largest of those measured that keeps the servos below their torque limits).

Every row also has the TOPP-RA lower bound of its task's execution time under its own
velocity and acceleration bounds (speed cap s <= 1; NaN with a note if toppra is not
installed), execution time / bound, the largest path deviation between the control
samples (at every MuJoCo physics step, or along the kinematic loop's joint motion) and the
peak torque over its limit.

The grid is the shipped study dqcontrol/studies/table1.toml (`dqcontrol study table1`),
reduced by the options below. The cases run in parallel on all cores (or on a Dask cluster
with --scheduler) with a progress bar. Writes OUT/table1.md (settings, machine, wall time,
our figures beside the thesis's) and OUT/table1.csv, both atomically, each case's result to
OUT/table1_cases/ as it finishes, and each run's log to OUT/table1_runs/ (unless
--no-save-runs); prints the table at the end."""

_EPILOG = """\
examples:
  dqcontrol table1                         full grid in MuJoCo (32 cases)
  dqcontrol table1 --quick --simulator kinematic
  dqcontrol table1 --controllers p10 pf --periods 1 2 --workers 2
  dqcontrol table1 --controllers pf --control-period 0.001   the path-following rows at 1 kHz
  dqcontrol table1 --scheduler tcp://10.0.0.5:8786 --out /shared/results"""


def register(subparsers) -> None:
    """Add the ``table1`` subcommand."""
    p = subparsers.add_parser(
        "table1",
        help="reproduce the thesis's Table 1 (circle and sinusoid, Local vs p = 6, 10) with "
        "the path-following controller beside it",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_out_option(p, "results", "results folder")
    _add_grid_options(p)
    _add_execution_options(p)
    p.set_defaults(func=_run)


def _add_grid_options(p: argparse.ArgumentParser) -> None:
    """Add the options that select the cases of the grid and how they run: ``--quick``,
    ``--periods``, ``--trajectories``, ``--controllers``, ``--simulator`` and
    ``--control-period``."""
    p.add_argument(
        "--quick",
        action="store_true",
        help="reduced grid for CI: one period per trajectory (circle 1 s, sinusoid 2 s)",
    )
    p.add_argument(
        "--periods",
        nargs="+",
        type=float,
        metavar="T_TOT",
        help="only these T_tot [s] of the grid (circle: 8 4 2 1; sinusoid: 16 8 4 2)",
    )
    p.add_argument(
        "--trajectories",
        nargs="+",
        choices=("circle", "sinusoid"),
        metavar="TRAJ",
        help="only these trajectories (circle, sinusoid)",
    )
    p.add_argument(
        "--controllers",
        nargs="+",
        type=_controller,
        metavar="CTRL",
        help="only these controllers: local, p6, p10, pf (alias path-following)",
    )
    p.add_argument(
        "--simulator",
        choices=("mujoco", "kinematic"),
        default="mujoco",
        help="closed loop: MuJoCo physics (default) or the ideal kinematic loop",
    )
    p.add_argument(
        "--control-period",
        type=positive_float("s"),
        default=None,
        metavar="T",
        help="control period T [s] of every controller (default: the thesis's 0.05; "
        "0.001 runs the grid at 1 kHz)",
    )


def _add_execution_options(p: argparse.ArgumentParser) -> None:
    """Add the options of how the cases run and what they keep: ``--workers``,
    ``--scheduler``, ``--no-save-runs``, ``--bound-samples`` and ``--no-progress``."""
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="processes of the local pool (default: all cores; 1 runs in this process)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a Dask distributed cluster, e.g. tcp://host:8786, or 'local' for a cluster "
        "of local worker processes (needs dask[distributed]; the run logs are then written on "
        "the workers' file system: give a shared --out)",
    )
    p.add_argument(
        "--no-save-runs",
        dest="save_runs",
        action="store_false",
        help="do not keep each run's log (.npz + .json) in OUT/table1_runs/",
    )
    p.add_argument(
        "--bound-samples",
        type=_bound_samples,
        default=None,
        metavar="N",
        help="path samples of the TOPP-RA bound (default: 2001; 0: no bound)",
    )
    add_progress_option(p)


def _controller(text: str) -> str:
    """A controller of the grid by its registry name or alias (argparse error if unknown)."""
    from dqcontrol.errors import ParameterError
    from dqcontrol.experiments.table1 import _canonical

    try:
        return _canonical(text)
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _bound_samples(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value != 0 and value < 10:
        raise argparse.ArgumentTypeError(f"expected 0 or an integer >= 10, got {text!r}")
    return value


def _run(args: argparse.Namespace) -> int:
    """The shipped ``table1`` study (:mod:`dqcontrol.studies`) with the options' selection."""
    from dqcontrol.cli._extras import check_simulator
    from dqcontrol.cli.study_cmd import run_with_options
    from dqcontrol.errors import ParameterError
    from dqcontrol.studies import load_study
    from dqcontrol.studies.table1_study import select_table1

    check_simulator(args.simulator)

    if args.workers is not None and args.workers < 1:
        raise ParameterError(f"--workers must be ≥ 1, got {args.workers}")
    study = select_table1(
        load_study("table1"),
        quick=args.quick,
        periods=args.periods,
        trajectories=args.trajectories,
        controllers=args.controllers,
        simulator=args.simulator,
        period_s=args.control_period,
        bound_samples=args.bound_samples,
        save_runs=args.save_runs,
    )
    if args.control_period is not None:
        _check_control_period(args.control_period, args.simulator, study.settings.horizon_s)
    result = run_with_options(study, args, _command_line(args))
    if result.interrupted:
        print(
            f"dqcontrol table1: interrupted; the completed cases are in {args.out}/table1.md",
            file=sys.stderr,
        )
        return 130
    print(result.texts["md"])
    runs = f"; run logs in {args.out}/table1_runs" if study.output.save_runs else ""
    print(f"wrote {result.files['md']} and {result.files['csv']}{runs}")
    failures = [r["case"] for r in result.results if r["interrupted"]]
    if failures:
        names = ", ".join(
            f"{c['trajectory']}_T{c['duration_s']:g}s_{c['controller']}" for c in failures
        )
        print(f"dqcontrol table1: some runs stopped early: {names}", file=sys.stderr)
        return 1
    return 0


def _check_control_period(period_s: float, simulator: str, horizon_s: float) -> None:
    """``--control-period`` shorter than the horizon and, in MuJoCo, a whole number of
    physics steps (a :class:`~dqcontrol.errors.ParameterError` naming the option)."""
    from dqcontrol.errors import ParameterError

    if not period_s < horizon_s:
        raise ParameterError(
            f"--control-period T must be shorter than the horizon tau_p = {horizon_s:g} s, "
            f"got {period_s:g}"
        )
    message = physics_steps_error("--control-period", period_s)
    if simulator == "mujoco" and message is not None:
        raise ParameterError(message)


def _command_line(args: argparse.Namespace) -> str:
    """The equivalent command line of the parsed options (quoted in the .md header)."""
    parts = ["dqcontrol", "table1", "--out", args.out]
    if args.quick:
        parts.append("--quick")
    for flag, values in (
        ("--periods", [f"{v:g}" for v in args.periods or ()]),
        ("--trajectories", args.trajectories or ()),
        ("--controllers", args.controllers or ()),
    ):
        if values:
            parts += [flag, *values]
    parts += ["--simulator", args.simulator]
    if args.control_period is not None:
        parts += ["--control-period", f"{args.control_period:g}"]
    if args.bound_samples is not None:
        parts += ["--bound-samples", str(args.bound_samples)]
    if args.workers is not None:
        parts += ["--workers", str(args.workers)]
    if args.scheduler:
        parts += ["--scheduler", args.scheduler]
    if not args.save_runs:
        parts.append("--no-save-runs")
    return shlex.join(parts)
