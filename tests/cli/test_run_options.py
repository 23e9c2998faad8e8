"""The options of ``dqcontrol run`` (dqcontrol/cli/run_options.py): their argparse types
(numbers with units, lists, controller names), the physics-step check of a period, the
groups and defaults of the parser, and the help's forms and units."""

from __future__ import annotations

import argparse

import pytest

from dqcontrol.cli import main
from dqcontrol.cli.run_options import (
    DEFAULT_CONTROLLERS,
    add_run_options,
    float_list,
    parse_controllers,
    physics_steps_error,
    positive_float,
)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="run")
    add_run_options(parser)
    return parser


@pytest.mark.parametrize("period", [0.001, 0.01, 0.05, 0.002, 1.0])
def test_a_whole_number_of_physics_steps_is_accepted(period):
    assert physics_steps_error("--period", period) is None


@pytest.mark.parametrize("period", [0.0015, 0.0005, 0.0, -0.001, 0.0101])
def test_a_period_between_physics_steps_is_refused_naming_the_option(period):
    message = physics_steps_error("--control-period", period)
    assert message is not None and message.startswith("--control-period: with --simulator ")
    assert f"got {period:g}" in message and "whole number of 0.001 s" in message


def test_positive_float_names_its_unit():
    parse = positive_float("rad/s^2")
    assert parse("2.5") == 2.5 and parse("1e-3") == 0.001
    for text, message in (
        ("two", "expected a number [rad/s^2], got 'two'"),
        ("0", "must be finite and > 0 [rad/s^2], got '0'"),
        ("-1", "must be finite and > 0 [rad/s^2], got '-1'"),
        ("nan", "must be finite and > 0 [rad/s^2], got 'nan'"),
        ("inf", "must be finite and > 0 [rad/s^2], got 'inf'"),
    ):
        with pytest.raises(argparse.ArgumentTypeError) as info:
            parse(text)
        assert str(info.value) == message


def test_float_list_reads_comma_separated_finite_numbers():
    assert float_list("0.1, -0.2,0.3") == (0.1, -0.2, 0.3)
    assert float_list("1,") == (1.0,)
    for text in ("", ",", "1,x", "1,nan", "inf"):
        with pytest.raises(argparse.ArgumentTypeError, match="comma-separated"):
            float_list(text)


def test_controllers_are_the_registrys_names_each_once():
    assert parse_controllers("local,p10,path-following") == ("local", "p10", "pf")
    assert parse_controllers("pf, PF,,local") == ("pf", "local")
    with pytest.raises(argparse.ArgumentTypeError, match="give at least one controller"):
        parse_controllers(" , ")
    with pytest.raises(argparse.ArgumentTypeError, match="unknown controller 'mpc'"):
        parse_controllers("local,mpc")


def test_unknown_controller_lists_the_known_ones(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--controllers", "mpc"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    for known in ("local", "p10", "noscale", "proportional", "pf", "path-following"):
        assert known in err, known


def test_the_defaults_are_the_theses_run():
    args = _parser().parse_args([])
    assert args.controllers == DEFAULT_CONTROLLERS == ("local", "p10", "pf")
    assert (args.period, args.horizon, args.duration) == (0.05, 1.0, 2.0)
    assert args.robot == "lbr4p" and args.trajectory == "circle" and args.simulator == "mujoco"
    assert args.gain is None and args.acceleration_limit is None and args.q0 is None
    assert args.obstacle == [] and args.self_collision is False and args.safety_distance == 0.02
    assert args.connect is None and args.realtime is False and args.viewer is False
    assert args.out == "results" and args.progress is True and args.speed == 1.0


def test_obstacles_repeat_and_a_negative_q0_needs_the_equals_sign():
    args = _parser().parse_args(
        ["--obstacle", "plane:0,0,1,0.45", "--obstacle", "sphere:0,0,1,0.1", "--q0=-0.2,0.5"]
    )
    assert args.obstacle == ["plane:0,0,1,0.45", "sphere:0,0,1,0.1"]
    assert args.q0 == (-0.2, 0.5)


def test_the_help_gives_the_forms_and_units(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    for form in ("sphere:X,Y,Z,R", "box:X,Y,Z,SX,SY,SZ", "plane:NX,NY,NZ,D", "metres"):
        assert form in out
