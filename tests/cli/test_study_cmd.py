"""``dqcontrol study`` (dqcontrol/cli/study_cmd.py): its options, the command line quoted in
the report, the executor options handed to the study runner, a missing or bad study file →
one line naming the problem and exit code 2, ``--list``, and a run stopped early → exit
code 1."""

from __future__ import annotations

import argparse

import pytest
from studies.small_study import SMALL, write_study

from dqcontrol.cli import build_parser, main
from dqcontrol.cli.study_cmd import BAD_INPUT, _command_line, _workers, run_with_options
from dqcontrol.studies import StudyFileError, load_study, tracking


def test_workers_is_an_integer_of_at_least_one():
    assert _workers("4") == 4
    for text in ("0", "-1", "x", "2.5"):
        with pytest.raises(argparse.ArgumentTypeError, match=f"got {text!r}"):
            _workers(text)


def test_the_quoted_command_line_has_the_options_given():
    args = build_parser().parse_args(["study", "my study.toml"])
    assert args.out is None and args.workers is None and not args.list
    assert _command_line(args) == "dqcontrol study 'my study.toml'"
    args = build_parser().parse_args(
        ["study", "faults", "--out", "res", "--workers", "2", "--scheduler", "local"]
    )
    assert _command_line(args) == ("dqcontrol study faults --out res --workers 2 --scheduler local")


def test_the_executor_options_reach_the_runner(monkeypatch):
    import dqcontrol.studies as studies

    calls = []
    monkeypatch.setattr(studies, "run_study", lambda study, **kw: calls.append((study, kw)))
    args = build_parser().parse_args(["study", "x.toml", "--workers", "3", "--no-progress"])
    run_with_options("STUDY", args, "the command")
    assert calls == [(
        "STUDY",
        {"out": None, "workers": 3, "scheduler": None, "progress": False,
         "command": "the command"},
    )]  # fmt: skip


def test_a_missing_study_file_is_one_line_and_exit_code_2(tmp_path, capsys):
    assert main(["study", str(tmp_path / "none.toml")]) == BAD_INPUT == 2
    err = capsys.readouterr().err
    assert err.startswith("dqcontrol study: error: ") and err.count("\n") == 1
    assert "none.toml" in err


def test_bad_workers_exit_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["study", "table1", "--workers", "0"])
    assert exc.value.code == 2
    assert "expected an integer >= 1, got '0'" in capsys.readouterr().err


def test_list_prints_the_cases(capsys):
    assert main(["study", "table1", "--list"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "circle_T8s_local" and out[-1] == "32 cases (table1, mujoco)"


def test_a_run_stopped_early_is_exit_code_1(tmp_path, monkeypatch, capsys):
    real = tracking.run_tracking_case

    def unstable_p10(case, study, save_dir=None):
        result = real(case, study, save_dir)
        if case.controller == "p10":
            result["interrupted"], result["note"] = True, "the physics became unstable"
        return result

    monkeypatch.setattr(tracking, "run_tracking_case", unstable_p10)
    path = write_study(tmp_path, SMALL)
    argv = ["study", str(path), "--workers", "1", "--no-progress", "--out", str(tmp_path)]
    assert main(argv) == 1
    assert "some runs stopped early: circle_T1s_p10" in capsys.readouterr().err
    assert "| circle | 1 | p=10 |" in (tmp_path / "small.md").read_text()


@pytest.mark.parametrize(
    ("old", "new", "fragments"),
    [
        (
            '"p10"]',
            '"mpc"]',
            ["[grid] controllers", "unknown controller 'mpc'", "local, p6, p10", "pf"],
        ),
        (
            "[options.p10]",
            "[options.p10]\nhorizn_s = 1.0",
            ["unknown key 'horizn_s' in [options.p10]", "horizon_s"],
        ),
        ("[grid]", "[grdi]", ["unknown key 'grdi' at the top level", "grid"]),
        (
            "period_s = 0.05",
            'period_s = "fast"',
            ["[simulator] period_s", "expected a finite number > 0 [s]", "'fast' (str)"],
        ),
        ("radius_m = 0.05", "radius_m = -0.05", ["[[trajectories]] #1", "radius_m"]),
        ('kind = "circle"', 'kind = "square"', ["unknown trajectory 'square'", "waypoints"]),
        ('name = "small"', 'name = "small"\nexperiment = "x"', ["unknown experiment 'x'"]),
        ('kind = "kinematic"', 'kind = "gazebo"', ["[simulator] kind", "'mujoco', 'kinematic'"]),
        ("duration_s = [1.0]", "duration_s = []", ["[grid] duration_s", "non-empty list"]),
        ("[grid]", "[grid", ["not a valid TOML file"]),
        (
            "acceleration_limit = 10.0",
            "velocity_limits = [1.0, 2.0]",
            ["[options]: controller 'local' cannot be built", "shape (7,)"],
        ),
        (
            "period_s = 0.05",
            "period_s = -0.05",
            ["[simulator] period_s", "expected a finite number > 0 [s]", "-0.05"],
        ),
        (
            "[grid]",
            '[robot]\nurdf = "no_such_arm.urdf"\ntool_frame = "flange"\nq0_rad = [0.0]\n\n[grid]',
            ["[robot] urdf", "no_such_arm.urdf"],
        ),
    ],
    ids=[
        "controller",
        "option",
        "table",
        "type",
        "value",
        "trajectory",
        "experiment",
        "simulator",
        "empty",
        "toml",
        "option value",
        "negative period",
        "missing robot",
    ],
)
def test_bad_study_file_is_a_clear_error_with_exit_code_2(tmp_path, capsys, old, new, fragments):
    assert old in SMALL
    path = write_study(tmp_path, SMALL.replace(old, new, 1))
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    message = str(info.value)
    assert message.startswith(str(path))
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    assert main(["study", str(path), "--no-progress", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dqcontrol study: error: ") and fragments[0] in err
    assert "Traceback" not in err


def test_missing_file_names_the_shipped_studies(tmp_path, capsys):
    assert main(["study", str(tmp_path / "none.toml")]) == 2
    err = capsys.readouterr().err
    assert "no study file" in err and "none.toml" in err and "table1, faults" in err
