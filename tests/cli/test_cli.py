"""The ``dqcontrol`` command as a whole (``dqcontrol.cli.main`` over every subcommand):
``--help`` everywhere, help texts free of project history, and bad options of any
subcommand → a clear message and exit code 2."""

from __future__ import annotations

import re

import pytest

from dqcontrol.cli import build_parser, main

_SUBCOMMANDS = ("run", "table1", "faults", "view", "bench", "sim-server")


def test_every_subcommand_has_help(capsys):
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    assert {"run", "view"} <= set(commands)
    for name in commands:
        with pytest.raises(SystemExit) as exc:
            main([name, "--help"])
        assert exc.value.code == 0
        assert f"usage: dqcontrol {name}" in capsys.readouterr().out


def test_help_texts_speak_of_the_tool_only(capsys):
    """No project-history words (issue numbers, work rounds or stages) in any help text."""
    for name in _SUBCOMMANDS:
        with pytest.raises(SystemExit):
            main([name, "--help"])
        text = capsys.readouterr().out
        assert not re.search(r"\b(issue|round|stage)s?\b", text, re.IGNORECASE), name
        if name in ("run", "sim-server"):
            for option in ("--lock", "--package-dir", "--tool", "erd:NAME"):
                assert option in text, (name, option)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["run", "--controllers", "local,mpc"], "unknown controller 'mpc'"),
        (["run", "--controllers", "p1"], "unknown controller 'p1'"),
        (["run", "--controllers", "pf1"], "unknown controller 'pf1'"),
        (["table1", "--controllers", "mpc"], "unknown controller 'mpc' for Table 1"),
        (["table1", "--bound-samples", "3"], "expected 0 or an integer >= 10"),
        (["run", "--period", "0.0015"], "whole number of 0.001 s physics steps"),
        (["run", "--period", "-0.05"], "must be finite and > 0"),
        (["run", "--period", "3"], "longer than T_tot"),
        (["run", "--duration", "two"], "expected a number"),
        (["run", "--trajectory", "square"], "invalid choice: 'square'"),
        (["run", "--simulator", "bullet"], "invalid choice: 'bullet'"),
        (["run", "--robot", "/no/such/robot.urdf"], "neither lbr4p, panda, erd:NAME nor"),
        (["run", "--ee-frame", "hand"], "unknown end-effector frame 'hand'"),
        (["run", "--q0", "0,1"], "the robot has 7 joints"),
        (["run", "--velocity-limits", "1,2,3"], "give 1 or 7 values"),
        (["run", "--speed", "0"], "must be finite and > 0"),
        (["run", "--hold", "-1"], "--hold must be >= 0"),
        (["run", "--no-such-option"], "unrecognized arguments"),
        (["view", "no_such_run.npz"], "no saved run"),
    ],
)
def test_bad_options_exit_2_with_a_clear_message(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert re.search(rf"^dqcontrol( {argv[0]})?: error: ", err, re.MULTILINE), err
    assert message in err
    assert "Traceback" not in err


def test_no_subcommand_prints_the_help_and_exits_2(capsys):
    assert main([]) == 2
    out = capsys.readouterr().out
    assert "usage: dqcontrol" in out and "run" in out and "view" in out


def test_a_library_error_is_one_line_with_exit_code_1(monkeypatch, capsys):
    from dqcontrol.cli import bench_cmd
    from dqcontrol.errors import ParameterError

    def fail():
        raise ParameterError("the reason")

    monkeypatch.setattr(bench_cmd, "load_bench", fail)
    assert main(["bench"]) == 1
    assert capsys.readouterr().err == "dqcontrol bench: error: the reason\n"


def test_ctrl_c_exits_130(monkeypatch, capsys):
    from dqcontrol.cli import bench_cmd

    def interrupt():
        raise KeyboardInterrupt

    monkeypatch.setattr(bench_cmd, "load_bench", interrupt)
    assert main(["bench"]) == 130
    assert capsys.readouterr().err == "dqcontrol bench: interrupted\n"
