"""``dqcontrol bench``: control-step and kinematics timings with peer ratios."""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "bench",
        help="time the control step of every controller and the kinematics",
        description="Median and 99th-percentile step times of every controller on the "
        "LBR4p (both QP backends), kinematics, step time against p and joint count, and "
        "ratios against DQ Robotics measured in the same run (if installed).",
    )
    parser.add_argument("--out", default="results/bench.json", help="JSON output file")
    parser.add_argument("--quick", action="store_true", help="fewer steps, no scaling sweep")
    parser.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from dqcontrol.bench import main

    main(out=args.out, quick=args.quick)
    return 0
