"""``dqcontrol study``: run the grid a study file describes and write its tables."""

from __future__ import annotations

import argparse
import shlex
import sys

from dqcontrol.cli.common import add_out_option, add_progress_option

__all__ = ["register"]

_DESCRIPTION = """\
Run a study: the cases a TOML study file describes (robot, trajectories, controllers and
their options, T_tot values, simulator and control period), on all cores of this machine or
on a Dask cluster, with a progress bar. Each finished case is saved at once, atomically, to
OUT/<name>_cases/<case>.json (an interrupt loses nothing that finished); the tables go to
OUT/<name>.md and OUT/<name>.csv.

STUDY is the path of a .toml file or the name of a shipped study: 'table1' (the thesis's
Table 1, as `dqcontrol table1`), 'faults' (the fault campaign, as `dqcontrol faults`) or
'arms' (serial arms of example-robot-data × every controller, docs/arms.md).
The format is described in docs/user_guide.md."""

_EPILOG = """\
examples:
  dqcontrol study my_study.toml
  dqcontrol study table1 --out results
  dqcontrol study faults --scheduler tcp://10.0.0.5:8786
  dqcontrol study my_study.toml --scheduler local --workers 2
  dqcontrol study faults --list"""

#: Exit code of a bad study file (argparse's code for bad input).
BAD_INPUT = 2


def register(subparsers) -> None:
    """Add the ``study`` subcommand."""
    p = subparsers.add_parser(
        "study",
        help="run the cases of a study file (or the shipped table1/faults studies)",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("study", metavar="STUDY", help="a .toml study file, or: table1, faults, arms")
    add_out_option(p, None, "results folder (default: the study's [output] folder)")
    p.add_argument(
        "--workers",
        type=_workers,
        default=None,
        metavar="N",
        help="processes of the local pool, or of the local Dask cluster (default: all cores; "
        "1 runs in this process)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a Dask distributed cluster, e.g. tcp://host:8786, or 'local' to start a "
        "cluster of local worker processes (needs dask[distributed])",
    )
    p.add_argument("--list", action="store_true", help="print the cases and exit")
    add_progress_option(p)
    p.set_defaults(func=_run)


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def _run(args: argparse.Namespace) -> int:
    from dqcontrol.studies import StudyFileError, load_study, study_cases
    from dqcontrol.studies.kinds import experiment_kind

    try:
        study = load_study(args.study)
    except StudyFileError as exc:
        print(f"dqcontrol study: error: {exc}", file=sys.stderr)
        return BAD_INPUT
    if args.list:
        name = experiment_kind(study.experiment).case_name
        cases = study_cases(study)
        for case in cases:
            print(name(case))
        loops = getattr(study.settings, "simulators", None) or (study.simulator,)
        print(f"{len(cases)} cases ({study.experiment}, {', '.join(loops)})")
        return 0
    result = run_with_options(study, args, _command_line(args))
    written = " and ".join(str(p) for p in result.files.values()) or "no table"
    print(
        f"{len(result.results)} of {result.total_cases} cases in {result.wall_time_s:.1f} s "
        f"({result.executor}); wrote {written}; case results in {result.cases_dir}"
    )
    if result.interrupted:
        print("dqcontrol study: interrupted; the tables hold the completed cases", file=sys.stderr)
        return 130
    cases = study_cases(study)
    name = experiment_kind(study.experiment).case_name
    stopped = [
        name(cases[i])
        for i, r in zip(result.indices, result.records, strict=True)
        if r.get("interrupted")
    ]
    if stopped:
        print(f"dqcontrol study: some runs stopped early: {', '.join(stopped)}", file=sys.stderr)
        return 1
    return 0


def _command_line(args: argparse.Namespace) -> str:
    parts = ["dqcontrol", "study", args.study]
    for flag, value in (("--out", args.out), ("--workers", args.workers)):
        if value is not None:
            parts += [flag, str(value)]
    if args.scheduler:
        parts += ["--scheduler", args.scheduler]
    return shlex.join(parts)


def run_with_options(study, args: argparse.Namespace, command: str):
    """Run ``study`` with the executor and output options every study command takes
    (``--out``, ``--workers``, ``--scheduler``, ``--no-progress``); ``command`` is quoted in
    the report."""
    from dqcontrol.studies import run_study

    return run_study(
        study,
        out=args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=args.progress,
        command=command,
    )
