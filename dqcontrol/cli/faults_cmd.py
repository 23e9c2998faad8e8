"""``dqcontrol faults``: the fault campaign → ``<out>/faults.md`` and ``.csv``.

Every controller on the circle and the sinusoid under measurement noise and delay, model
mismatch, torque saturation, impossible tasks, awkward starts and failing or contradictory
QPs (:mod:`dqcontrol.faults`). The cases are those of the shipped study
``dqcontrol/studies/faults.toml`` reduced by the options, run by :mod:`dqcontrol.studies` on
every core (or a Dask cluster). Both files are written atomically, and each case's result
as it finishes; Ctrl-C writes the cases completed so far, marked as incomplete.
"""

from __future__ import annotations

import argparse
import sys

from dqcontrol.cli.common import add_out_option, add_progress_option

__all__ = ["register", "run"]


def _csv_list(text: str) -> list[str]:
    items = [t.strip() for t in text.split(",") if t.strip()]
    if not items:
        raise argparse.ArgumentTypeError("expected a comma-separated list of names")
    return items


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        msg = f"--workers must be an integer ≥ 1, got {text!r}"
        raise argparse.ArgumentTypeError(msg) from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"--workers must be an integer ≥ 1, got {value}")
    return value


def register(subparsers) -> None:
    """Add the ``faults`` subcommand."""
    from dqcontrol.faults.scenarios import CONTROLLERS, FAULTS, TRAJECTORIES

    parser = subparsers.add_parser(
        "faults",
        help="run the fault campaign and write faults.md / faults.csv",
        description=(
            "Run every controller on the circle and the sinusoid under faults (noise, delay, "
            "payload, torque saturation, unreachable path, far/singular/near-limit starts, "
            "contradictory QPs, failing solvers) and report completion, σ reached, e_mean, "
            "path deviation, bound violations, fallbacks and NaN. Writes <out>/faults.md "
            "and <out>/faults.csv atomically."
        ),
        epilog=(
            f"controllers: {', '.join(CONTROLLERS)}. trajectories: {', '.join(TRAJECTORIES)}. "
            f"faults: {', '.join(f.name for f in FAULTS)}."
        ),
    )
    add_out_option(parser, "results", "results folder")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="reduced campaign (5 controllers, the circle, one fault of each kind)",
    )
    parser.add_argument(
        "--simulator",
        choices=("mujoco", "kinematic"),
        default="mujoco",
        help="closed loop: MuJoCo dynamics (default) or ideal velocity tracking",
    )
    parser.add_argument(
        "--workers",
        type=_workers,
        default=None,
        help="processes of the local pool (default: all cores; 1 runs in this process)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a Dask distributed cluster, e.g. tcp://host:8786, or 'local' for a "
        "cluster of local worker processes (needs dask[distributed])",
    )
    parser.add_argument(
        "--controllers", type=_csv_list, default=None, help="comma-separated subset"
    )
    parser.add_argument(
        "--trajectories", type=_csv_list, default=None, help="comma-separated subset"
    )
    parser.add_argument("--faults", type=_csv_list, default=None, help="comma-separated subset")
    parser.add_argument("--seed", type=int, default=0, help="seed of the measurement noise")
    parser.add_argument(
        "--strict",
        action="store_true",
        help="exit with code 1 if a QP controller violated a bound, saw NaN or raised",
    )
    add_progress_option(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the campaign (the shipped ``faults`` study with the options' selection), write
    the report, print a summary. Exit code: 0, 1 (``--strict`` and a QP controller failed a
    check), 130 (interrupted; the partial report is written)."""
    from dqcontrol.cli._extras import check_simulator
    from dqcontrol.cli.study_cmd import run_with_options
    from dqcontrol.studies import load_study
    from dqcontrol.studies.faults_study import campaign_result, select_faults

    check_simulator(args.simulator)
    study = select_faults(
        load_study("faults"),
        controllers=args.controllers,
        trajectories=args.trajectories,
        faults=args.faults,
        simulator=args.simulator,
        quick=args.quick,
        seed=args.seed,
    )
    done = run_with_options(study, args, _command_line(args))
    result = campaign_result(
        study,
        done.results,
        total_cases=done.total_cases,
        interrupted=done.interrupted,
        wall_time_s=done.wall_time_s,
    )
    md_path, csv_path = done.files["md"], done.files["csv"]
    qp = result.qp_rows
    unsafe = [r for r in qp if not r.safe]
    print(f"wrote {md_path} and {csv_path} ({len(result.rows)} cases, {result.wall_time_s:.0f} s)")
    print(
        f"QP controllers: {len(qp) - len(unsafe)}/{len(qp)} cases without violation, NaN or "
        "exception"
    )
    for r in unsafe:
        print(f"  {r.fault}/{r.trajectory}/{r.controller}: {_what_failed(r)}")
    if result.interrupted:
        print(f"interrupted: {result.note}; the report holds the completed cases", file=sys.stderr)
        return 130
    return 1 if (args.strict and unsafe) else 0


def _command_line(args: argparse.Namespace) -> str:
    """The options that select the cases, quoted in the report."""
    parts = ["dqcontrol faults", f"--simulator {args.simulator}"]
    if args.quick:
        parts.append("--quick")
    for name in ("controllers", "trajectories", "faults"):
        value = getattr(args, name)
        if value:
            parts.append(f"--{name} {','.join(value)}")
    return " ".join(parts)


def _what_failed(r) -> str:
    """The checks a QP controller's row failed, as one line."""
    what = []
    if r.raised:
        what.append(f"raised {r.raised}")
    if r.nan_seen:
        what.append("NaN")
    if r.velocity_violations or r.acceleration_violations:
        what.append(f"command violations {r.velocity_violations}/{r.acceleration_violations}")
    if r.q_violations_true:
        what.append(
            f"{r.q_violations_true} joint positions beyond a limit "
            f"(max {1000 * r.q_excess_true_rad:.2f} mrad)"
        )
    if not (r.sigma_monotone and r.s_in_range):
        what.append("σ decreased or s outside [0, 1]")
    return ", ".join(what)
