"""``dqcontrol faults`` (dqcontrol/cli/faults_cmd.py): its option types, its defaults (every
core), the command line quoted in the report, the line that says what a QP controller's case
failed, help and bad options, and small campaigns run by the command (the report written
atomically, the path-following controller)."""

from __future__ import annotations

import argparse
import csv
import os
from types import SimpleNamespace

import pytest

from dqcontrol.cli import build_parser, main
from dqcontrol.cli.faults_cmd import _command_line, _csv_list, _what_failed, _workers
from dqcontrol.experiments.executor import resolve_executor


def test_a_list_option_is_comma_separated_names():
    assert _csv_list(" local, p10 ,,pf") == ["local", "p10", "pf"]
    with pytest.raises(argparse.ArgumentTypeError, match="comma-separated list of names"):
        _csv_list(" , ")


@pytest.mark.parametrize(
    ("text", "message"),
    [("0", "got 0"), ("-2", "got -2"), ("two", "got 'two'"), ("1.5", "got '1.5'")],
)
def test_workers_is_an_integer_of_at_least_one(text, message):
    assert _workers("3") == 3
    with pytest.raises(argparse.ArgumentTypeError) as info:
        _workers(text)
    assert str(info.value) == f"--workers must be an integer ≥ 1, {message}"


def test_the_defaults_and_the_quoted_command_line():
    args = build_parser().parse_args(["faults"])
    assert (args.out, args.simulator, args.workers, args.seed) == ("results", "mujoco", None, 0)
    assert not (args.quick or args.strict) and args.progress
    assert _command_line(args) == "dqcontrol faults --simulator mujoco"
    args = build_parser().parse_args(
        ["faults", "--quick", "--simulator", "kinematic", "--controllers", "local,pf",
         "--faults", "noise", "--seed", "3", "--workers", "2"]
    )  # fmt: skip
    assert _command_line(args) == (
        "dqcontrol faults --simulator kinematic --quick --controllers local,pf --faults noise"
    )


def test_a_bad_workers_option_exits_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["faults", "--workers", "0"])
    assert exc.value.code == 2
    assert "--workers must be an integer ≥ 1, got 0" in capsys.readouterr().err


def _row(**failed):
    clean = {
        "raised": "", "nan_seen": False, "velocity_violations": 0,
        "acceleration_violations": 0, "q_violations_true": 0, "q_excess_true_rad": 0.0,
        "sigma_monotone": True, "s_in_range": True,
    }  # fmt: skip
    return SimpleNamespace(**{**clean, **failed})


def test_what_a_case_failed_is_one_line():
    assert _what_failed(_row()) == ""
    assert _what_failed(_row(raised="QPError")) == "raised QPError"
    assert _what_failed(_row(velocity_violations=2)) == "command violations 2/0"
    assert _what_failed(
        _row(nan_seen=True, acceleration_violations=1, q_violations_true=3,
             q_excess_true_rad=0.00125, s_in_range=False)
    ) == (
        "NaN, command violations 0/1, 3 joint positions beyond a limit (max 1.25 mrad), "
        "σ decreased or s outside [0, 1]"
    )  # fmt: skip


def test_cli_writes_the_report_atomically(tmp_path, capsys):
    code = main(
        ["faults", "--quick", "--simulator", "kinematic", "--controllers", "local,proportional",
         "--faults", "nominal,solver_fails", "--out", str(tmp_path), "--no-progress"]
    )  # fmt: skip
    assert code == 0
    md = (tmp_path / "faults.md").read_text(encoding="utf-8")
    assert "solver_fails" in md and "simulator **kinematic**" in md
    assert len(list(csv.DictReader(open(tmp_path / "faults.csv", encoding="utf-8")))) == 3
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp files
    out = capsys.readouterr().out
    assert "wrote" in out and "2/2 cases without violation" in out


def test_cli_help_and_bad_options(capsys):
    with pytest.raises(SystemExit) as info:
        main(["faults", "--help"])
    assert info.value.code == 0
    assert "--simulator" in capsys.readouterr().out
    with pytest.raises(SystemExit) as info:
        main(["faults", "--workers", "0"])
    assert info.value.code == 2
    assert main(["faults", "--controllers", "pid", "--out", "/nonexistent"]) == 1


PF = "path_following"


def test_the_cli_runs_the_path_following_controller(tmp_path, capsys):
    code = main(
        ["faults", "--simulator", "kinematic", "--controllers", PF, "--faults",
         "nominal,qp_crossed", "--trajectories", "circle", "--out", str(tmp_path),
         "--workers", "1", "--no-progress"]
    )  # fmt: skip
    assert code == 0
    rows = list(csv.DictReader(open(tmp_path / "faults.csv", encoding="utf-8")))
    assert [(r["fault"], r["controller"], r["status"]) for r in rows] == [
        ("nominal", PF, "completed"),
        ("qp_crossed", PF, "completed"),
    ]
    assert "2/2 cases without violation" in capsys.readouterr().out


def test_fault_campaign_defaults_to_every_core():
    from dqcontrol.cli import build_parser

    args = build_parser().parse_args(["faults"])
    assert args.workers is None and args.scheduler is None
    assert resolve_executor(args.workers, None, 1000).workers == (os.cpu_count() or 1)
    assert resolve_executor(None, None, 1).label == "in-process (1 worker)"
