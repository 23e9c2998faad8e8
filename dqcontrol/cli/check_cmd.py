"""``dqcontrol check``: list every sample of a saved run a real arm would have refused.

The run's applied commands are replayed at its period against a limit profile
(:func:`dqcontrol.runs.check.check_run`); one line per violation, then one summary line
(``check PASS`` / ``check FAIL``). Exit code 0: no violation; 1: violations; 2: bad input
(no such run, an unknown or bad profile, a profile for other joints, no period).
"""

from __future__ import annotations

import argparse
import sys

from dqcontrol.cli.robot_options import limits_help

__all__ = ["register"]

_DESCRIPTION = """\
Replay a saved run's joint-velocity commands u_k at its period T and list every sample a
real arm's controller would have refused: the measured position outside its range, |u_k|
above the velocity limit, |(u_k - u_(k-1))/T| above the acceleration limit,
|(u_k - 2 u_(k-1) + u_(k-2))/T^2| above the jerk limit (the arm at rest before the first
command), and a last command that is not 0 (the motion does not end at rest). Each line
names the kind, the joint, the sample and its time, the value and the limit; the first is
the reflex that would have fired. A relative tolerance of 1e-9 applies to every limit.
The last line is a summary a CI can grep: 'check PASS ...' or 'check FAIL ...'.
Exit code: 0 no violation, 1 violations, 2 bad input."""

_EPILOG = """\
examples:
  dqcontrol check results/panda_circle_T1s_kinematic/pf.json --limits franka_panda
  dqcontrol check run.npz --limits my_arm.toml --period 0.001"""


def register(subparsers) -> None:
    """Add the ``check`` subcommand."""
    p = subparsers.add_parser(
        "check",
        help="list every sample of a saved run a real arm would refuse (limits, jerk, rest)",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", metavar="RUN", help="the saved run (.json, .npz, .mcap or stem)")
    p.add_argument(
        "--limits",
        metavar="NAME|FILE.toml",
        default=None,
        help=limits_help() + " (default: the run's own profile, else its URDF's limits)",
    )
    p.add_argument(
        "--period", type=float, default=None, metavar="S", help="control period T [s] "
        "(default: the run's)",
    )  # fmt: skip
    p.set_defaults(func=_main)


def _fail(message: str) -> int:
    print(f"dqcontrol check: error: {message}", file=sys.stderr)
    return 2


def _main(args: argparse.Namespace) -> int:
    from dqcontrol.errors import ParameterError
    from dqcontrol.runs.check import check_run, run_period, summary_line
    from dqcontrol.runs.storage import load_run, run_file

    path = run_file(args.run)
    if not path.is_file():
        return _fail(f"RUN: no saved run at {args.run!r}")
    try:
        log, _record = load_run(path)
        name, limits = _limits(args.limits, log.meta)
        period = run_period(log, args.period)
        violations = check_run(log, limits, period_s=period)
    except (ParameterError, OSError, ValueError) as exc:
        return _fail(str(exc))
    for v in violations:
        print(v.describe())
    print(summary_line(violations, len(log), period, name, path.name))
    return 1 if violations else 0


def _limits(option: str | None, meta: dict):
    """The profile's name and what to check against: the profile itself, or the robot's
    URDF limits (the robot rebuilt from the run's meta) for ``urdf``."""
    from dqcontrol.cli.robot_options import robot_from_meta
    from dqcontrol.errors import ParameterError
    from dqcontrol.model.limit_profile import load_profile

    profile = load_profile(option or meta.get("limits") or "urdf")
    if not profile.is_urdf:
        return profile.name, profile
    try:  # the robot as its URDF describes it, whatever profile the run had
        robot = robot_from_meta({k: v for k, v in meta.items() if k != "limits"})
    except ParameterError as exc:
        raise ParameterError(
            f"{exc}; without its robot, check against a profile: --limits NAME|FILE.toml"
        ) from None
    return profile.name, robot.limits
