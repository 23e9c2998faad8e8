"""``dqcontrol faults``: the fault campaign → ``<out>/faults.md`` and ``.csv``.

Every controller on the circle and the sinusoid under measurement noise and delay, model
mismatch, torque saturation, impossible tasks, awkward starts and failing or contradictory
QPs (:mod:`dqcontrol.faults`). Both files are written atomically; Ctrl-C writes the cases
completed so far, marked as incomplete.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dqcontrol.cli.common import add_out_option, add_progress_option
from dqcontrol.errors import ParameterError

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
        help="reduced campaign (4 controllers, the circle, one fault of each kind)",
    )
    parser.add_argument(
        "--simulator",
        choices=("mujoco", "kinematic"),
        default="mujoco",
        help="closed loop: MuJoCo dynamics (default) or ideal velocity tracking",
    )
    parser.add_argument("--workers", type=_workers, default=1, help="worker processes (default: 1)")
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
    """Run the campaign, write the report, print a summary. Exit code: 0, 1 (``--strict``
    and a QP controller failed a check), 130 (interrupted; the partial report is written)."""
    from tqdm import tqdm

    from dqcontrol.faults.campaign import (
        campaign_cases,
        render_csv,
        render_markdown,
        run_campaign,
    )
    from dqcontrol.runs.storage import atomic_write_text

    cases = campaign_cases(
        args.controllers, args.trajectories, args.faults, args.simulator, args.quick, args.seed
    )
    if not cases:
        raise ParameterError("the selection has no case (check --controllers/--faults)")
    bar = tqdm(
        total=len(cases),
        desc=f"faults ({args.simulator})",
        unit="case",
        disable=not args.progress,
        file=sys.stderr,
    )

    def on_result(row, done, total):
        bar.set_postfix_str(f"{row.fault}/{row.trajectory}/{row.controller}", refresh=False)
        bar.update(1)

    try:
        result = run_campaign(
            args.controllers,
            args.trajectories,
            args.faults,
            args.simulator,
            args.quick,
            workers=args.workers,
            seed=args.seed,
            on_result=on_result,
        )
    finally:
        bar.close()
    parts = ["dqcontrol faults", f"--simulator {args.simulator}"]
    if args.quick:
        parts.append("--quick")
    for name in ("controllers", "trajectories", "faults"):
        value = getattr(args, name)
        if value:
            parts.append(f"--{name} {','.join(value)}")
    command = " ".join(parts)
    out = Path(args.out)
    md_path = atomic_write_text(out / "faults.md", render_markdown(result, command=command))
    csv_path = atomic_write_text(out / "faults.csv", render_csv(result))
    qp = result.qp_rows
    unsafe = [r for r in qp if not r.safe]
    print(f"wrote {md_path} and {csv_path} ({len(result.rows)} cases, {result.wall_time_s:.0f} s)")
    print(
        f"QP controllers: {len(qp) - len(unsafe)}/{len(qp)} cases without violation, NaN or "
        "exception"
    )
    for r in unsafe:
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
        print(f"  {r.fault}/{r.trajectory}/{r.controller}: {', '.join(what)}")
    if result.interrupted:
        print(f"interrupted: {result.note}; the report holds the completed cases", file=sys.stderr)
        return 130
    return 1 if (args.strict and unsafe) else 0
