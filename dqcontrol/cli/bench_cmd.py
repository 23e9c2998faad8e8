"""``dqcontrol bench``: control-step and kinematics timings with peer ratios."""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "bench",
        help="time the control step of every controller and the kinematics (issue 7's figures)",
        description="Every figure of the performance issue at T = 1 ms on the LBR4p: the "
        "median and 99th-percentile step times of the local, predictive (p = 6, 10) and "
        "proportional controllers on both QP backends, the backends' agreement, kinematics, "
        "ratios against DQ Robotics measured in the same run (if installed), the MuJoCo "
        "closed loop's real-time factor (p = 10, T = 1 ms, 2 s circle), and the step time "
        "against p and the joint count. Each target is printed as met or not met; the "
        "figures and the machine go to a JSON file (about a minute; --quick: seconds).",
    )
    parser.add_argument("--out", default="results/bench.json", help="JSON output file")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="few steps and a reduced sweep (seconds; indicative figures only)",
    )
    parser.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from dqcontrol.bench import main

    main(out=args.out, quick=args.quick)
    return 0
