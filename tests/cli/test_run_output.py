"""What ``dqcontrol run`` shows and writes (dqcontrol/cli/run_output.py): the metrics table
cell by cell, the progress bars' switch and callback, the collision line, the viewer's hold
and the streamed log loaded back — each against a hand-made input."""

from __future__ import annotations

import argparse
import math
from types import SimpleNamespace

import pytest

from dqcontrol.cli.run_output import (
    TABLE_LEGEND,
    _figure_settings,
    collision_report,
    hold_viewer,
    loaded_result,
    metrics_table,
    progress_callback,
    show_progress,
    with_contacts,
)


def _metrics(**changes):
    values = {
        "completed": True, "execution_time_s": 2.0504, "e_mean": 0.0012345, "e_max": 0.004,
        "path_deviation_max_m": 0.00031, "rotation_error_max_rad": math.radians(1.5),
        "u_mean_rad_s": 0.25, "s_mean": 0.9876, "torque_peak_nm": 12.34,
        "position_violations": 0, "velocity_violations": 1, "acceleration_violations": 2,
        "fallbacks": 3, "step_time_median_s": 0.00042,
    }  # fmt: skip
    return SimpleNamespace(**{**values, **changes})


def test_the_metrics_table_cell_by_cell():
    table = metrics_table(
        [("pf", _metrics()), ("a_very_long_name", _metrics(completed=False, torque_peak_nm=None))]
    )
    head, rule, first, second = table.splitlines()
    assert head.split() == [
        "controller", "done", "t_exec", "e_mean", "e_max", "dev_mm", "rot_deg", "u_mean",
        "s_mean", "tau_Nm", "viol", "fb", "step_ms",
    ]  # fmt: skip
    assert rule == "-" * len(head)
    assert first.split() == [
        "pf", "yes", "2.050", "0.00123", "0.00400", "0.31", "1.50", "0.250", "0.988", "12.3",
        "0/1/2", "3", "0.42",
    ]  # fmt: skip
    cells = second.split()
    assert cells[0] == "a_very_long_"  # cut to the column's 12 characters
    assert cells[1] == "NO" and cells[9] == "-"  # no torque (the kinematic loop)
    assert len(first) == len(head)


def test_a_non_finite_value_is_a_dash():
    (row,) = metrics_table([("x", _metrics(e_mean=math.nan, s_mean=math.inf))]).splitlines()[2:]
    cells = row.split()
    assert cells[3] == "-" and cells[8] == "-"
    assert "dev_mm: max path deviation [mm]" in TABLE_LEGEND


@pytest.mark.parametrize(
    ("progress", "short", "shown"),
    [(True, False, True), (False, False, False), (True, True, False), (False, True, False)],
)
def test_progress_bars_are_off_with_no_progress_or_short(progress, short, shown):
    assert show_progress(argparse.Namespace(progress=progress, short=short)) is shown


def test_the_progress_callback_advances_the_bar_to_sigma_and_never_back():
    bar = SimpleNamespace(total=2.0, n=0.0)

    def update(step):
        bar.n += step

    bar.update = update
    report = progress_callback(bar)
    for sigma in (0.5, 0.4, 1.25, 3.0):
        report(sigma, 2.0)
    assert bar.n == 2.0  # capped at the bar's total
    report(1.0, 2.0)
    assert bar.n == 2.0


def test_figures_are_smaller_in_short_mode():
    def args(svg, short):
        return argparse.Namespace(svg=svg, short=short)

    assert _figure_settings(args(False, False)) == ("png", 110.0, 30.0)
    assert _figure_settings(args(True, True)) == ("svg", 60.0, 10.0)


def test_the_collision_line_and_runs_without_a_collision_model():
    summary = SimpleNamespace(summary=lambda: "min distance 21.0 mm")
    assert collision_report("pf", SimpleNamespace(contacts=summary)) == "pf: min distance 21.0 mm"
    assert collision_report("pf", SimpleNamespace(contacts=None)) == "pf: no samples"
    runs = [("pf", object(), None)]
    assert with_contacts(runs, robot=None, collision=None) is runs


def test_hold_returns_at_once_without_a_terminal_or_a_time(capsys):
    viewer = SimpleNamespace(url="http://127.0.0.1:7000/static/")
    hold_viewer(viewer, None)  # pytest's stdin is not a terminal
    hold_viewer(viewer, 0.0)
    hold_viewer(viewer, -1.0)
    assert capsys.readouterr().out == ""


def test_a_result_without_a_readable_file_is_kept_as_it_is(tmp_path):
    no_file = SimpleNamespace(log_file=None, log_stride=1)
    assert loaded_result(no_file) is no_file
    decimated = SimpleNamespace(log_file=tmp_path / "run.mcap", log_stride=4)
    assert loaded_result(decimated) is decimated
    missing = SimpleNamespace(log_file=tmp_path / "missing.mcap", log_stride=1)
    assert loaded_result(missing) is missing
