"""``dqcontrol table1`` (dqcontrol/cli/table1_cmd.py): its option types, the control period
checked against the horizon and MuJoCo's physics step, the command line quoted in the
report, bad options → exit code 2 or one line with exit code 1, and the reduced grid run in
both simulators and at another control period (its table, report and saved runs)."""

from __future__ import annotations

import argparse
import csv
import math

import pytest

from dqcontrol.cli import build_parser, main
from dqcontrol.cli.table1_cmd import (
    _bound_samples,
    _check_control_period,
    _command_line,
    _controller,
)
from dqcontrol.errors import ParameterError
from dqcontrol.experiments import table1 as t1
from dqcontrol.runs.storage import load_run


def test_bound_samples_is_zero_or_at_least_ten():
    assert _bound_samples("0") == 0 and _bound_samples("10") == 10
    for text in ("9", "-1", "x", "1e3"):
        with pytest.raises(argparse.ArgumentTypeError, match="expected 0 or an integer >= 10"):
            _bound_samples(text)


def test_controllers_are_the_grids_by_name_or_alias():
    assert [_controller(t) for t in ("Local", "P6", "p10", "path-following")] == [
        "local", "p6", "p10", "pf",
    ]  # fmt: skip
    with pytest.raises(argparse.ArgumentTypeError, match="unknown controller 'p3' for Table 1"):
        _controller("p3")


def test_the_control_period_is_below_the_horizon_and_whole_physics_steps():
    _check_control_period(0.001, "mujoco", 1.0)
    _check_control_period(0.0015, "kinematic", 1.0)  # the kinematic loop has no physics step
    with pytest.raises(ParameterError, match="shorter than the horizon tau_p = 1 s, got 1"):
        _check_control_period(1.0, "kinematic", 1.0)
    with pytest.raises(ParameterError, match="--control-period: with --simulator mujoco"):
        _check_control_period(0.0015, "mujoco", 1.0)


def test_the_quoted_command_line():
    args = build_parser().parse_args(["table1"])
    assert _command_line(args) == "dqcontrol table1 --out results --simulator mujoco"
    args = build_parser().parse_args(
        ["table1", "--quick", "--periods", "1", "2.5", "--trajectories", "circle",
         "--controllers", "p10", "path-following", "--simulator", "kinematic",
         "--control-period", "0.01", "--bound-samples", "0", "--workers", "2",
         "--scheduler", "tcp://h:8786", "--no-save-runs", "--out", "my results"]
    )  # fmt: skip
    assert _command_line(args) == (
        "dqcontrol table1 --out 'my results' --quick --periods 1 2.5 --trajectories circle "
        "--controllers p10 pf --simulator kinematic --control-period 0.01 --bound-samples 0 "
        "--workers 2 --scheduler tcp://h:8786 --no-save-runs"
    )


def test_no_workers_is_one_line_with_exit_code_1(capsys):
    assert main(["table1", "--simulator", "kinematic", "--workers", "0"]) == 1
    assert capsys.readouterr().err == "dqcontrol table1: error: --workers must be ≥ 1, got 0\n"


def _read_csv(path):
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        return reader.fieldnames, list(reader)


@pytest.mark.parametrize("simulator", ["kinematic", "mujoco"])
def test_table1_command_reduced_grid(tmp_path, capsys, simulator):
    out = tmp_path / "results"
    argv = ["table1", "--quick", "--simulator", simulator, "--out", str(out)]
    code = main([*argv, "--workers", "1", "--no-progress", "--bound-samples", "201"])
    assert code == 0
    printed = capsys.readouterr().out
    header, rows = _read_csv(out / "table1.csv")
    assert header == [k for k, _, _ in t1.COLUMNS]
    for key in ("toppra_bound_s", "exec_over_bound", "path_dev_max_between_mm"):
        assert key in header
    assert len(rows) == 8
    md = (out / "table1.md").read_text()
    assert md in printed
    for _, title, _ in t1.COLUMNS:
        assert f" {title} |" in md, title
    for needed in ("3.1416, 3.1416", "7.8540", "10 rad/s²", "T = 0.05 s", "τ_p = 1 s", "K = 10"):
        assert needed in md, needed
    assert "wall time" in md and "CPUs" in md
    assert "## The thesis's claim at the short periods" in md
    assert "## The path-following rows (path-following)" in md and "201 path samples" in md
    assert ("MuJoCo" if simulator == "mujoco" else "kinematic loop") in md
    assert {r["controller"] for r in rows} == {"Local", "p=6", "p=10", "path-following"}
    for row in rows:
        assert row["completed"] == "yes"
        assert row["viol_position"] == row["viol_velocity"] == row["viol_acceleration"] == "0"
        thesis_row = row["controller"] != "path-following"
        assert bool(row["e_mean_thesis"] and row["u_mean_thesis"]) == thesis_row
        assert math.isfinite(float(row["e_mean"])) and 0.0 < float(row["s_mean"]) <= 1.0
        torque = float(row["torque_peak_nm"]) if row["torque_peak_nm"] else math.nan
        assert math.isfinite(torque) == (simulator == "mujoco")
        bound, ratio = float(row["toppra_bound_s"]), float(row["exec_over_bound"])
        assert float(row["T_tot_s"]) < bound < float(row["exec_time_s"]) + 1.0
        assert ratio == pytest.approx(float(row["exec_time_s"]) / bound, rel=1e-12)
        between, at = float(row["path_dev_max_between_mm"]), float(row["path_dev_max_mm"])
        assert between >= at - 1e-9  # the samples are among the states between them
    runs = sorted(p.name for p in (out / "table1_runs").iterdir())
    assert len(runs) == 16 and "circle_T1s_p10.npz" in runs and "circle_T1s_pf.npz" in runs
    log, record = load_run(out / "table1_runs" / "sinusoid_T2s_local.json")
    assert record["meta"]["simulator"] == simulator and len(log) == record["metrics"]["samples"]
    assert not [p for p in out.rglob("*.tmp")]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--periods", "3"], "not in the thesis's grid"),
        (["--control-period", "0.0015"], "whole number of 0.001 s physics steps"),
        (["--control-period", "1", "--simulator", "kinematic"], "shorter than the horizon"),
    ],
)
def test_bad_option_is_one_line_error(tmp_path, capsys, argv, message):
    assert main(["table1", *argv, "--out", str(tmp_path), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_table1_command_at_another_control_period(tmp_path):
    out = tmp_path / "results"
    argv = ["table1", "--controllers", "pf", "--trajectories", "circle", "--periods", "1",
            "--simulator", "kinematic", "--control-period", "0.005", "--out", str(out)]  # fmt: skip
    assert main([*argv, "--workers", "1", "--no-progress", "--bound-samples", "0"]) == 0
    md = (out / "table1.md").read_text()
    assert "control period T = 0.005 s" in md and "T = 0.05 s (not this table's)" in md
    assert "--control-period 0.005" in md
    _, (row,) = _read_csv(out / "table1.csv")
    assert row["completed"] == "yes" and float(row["path_dev_max_mm"]) <= 0.1
    _, record = load_run(out / "table1_runs" / "circle_T1s_pf.json")
    assert record["meta"]["period_s"] == 0.005
