"""The options of a streamed run (dqcontrol/cli/stream_options.py): ``--plan-period`` and
``--jerk-limit`` parsed and checked against ``--period`` and the controllers (bad ones → exit
code 2 from ``dqcontrol run``), the planner's half of the acceleration bound, the stream built
from them, and the summary line of a stream's report written by hand."""

from __future__ import annotations

import argparse

import pytest

from dqcontrol.cli.run_options import add_run_options
from dqcontrol.cli.stream_options import (
    check_stream_options,
    planner_acceleration,
    stream_summary,
    streamed_from_args,
)


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="dqcontrol run")
    add_run_options(parser)
    args = parser.parse_args(list(argv))
    args._parser = parser
    return args


def test_the_plan_period_is_seconds_or_auto():
    assert _args("--plan-period", "auto").plan_period == "auto"
    assert _args("--plan-period", "0.02").plan_period == 0.02
    assert _args().plan_period is None and _args().jerk_limit is None
    assert _args("--jerk-limit", "500").jerk_limit == 500.0


@pytest.mark.parametrize(
    "argv",
    [
        ["--plan-period", "0.05", "--controllers", "pf"],
        ["--plan-period", "auto", "--controllers", "pf"],
        ["--plan-period", "0.03", "--period", "0.01", "--controllers", "pf"],
        ["--plan-period", "0.01", "--period", "0.01", "--controllers", "pf", "--jerk-limit", "9"],
        [],
    ],
)
def test_consistent_stream_options_pass(argv):
    check_stream_options(_args(*argv))


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--jerk-limit", "500"], "--jerk-limit bounds the stream of --plan-period: give"),
        (
            ["--plan-period", "0.015", "--period", "0.01", "--controllers", "pf"],
            "--plan-period must be a whole multiple >= 1 of --period 0.01 s (e.g. 0.02), got 0.015",
        ),
        (
            ["--plan-period", "0.005", "--period", "0.01", "--controllers", "pf"],
            "(e.g. 0.01), got 0.005",
        ),
        (
            ["--plan-period", "0.1", "--controllers", "pf,local"],
            "--plan-period: local has no consistent plan to stream",
        ),
    ],
)
def test_inconsistent_stream_options_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        check_stream_options(_args(*argv))
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_the_planner_plans_with_half_the_streams_acceleration():
    assert planner_acceleration(_args("--acceleration-limit", "8")) == 4.0
    assert planner_acceleration(_args()) is None


def test_the_stream_takes_the_period_and_the_bounds(monkeypatch):
    import dqcontrol.streaming as streaming

    calls = []
    monkeypatch.setattr(streaming, "streamed", lambda *a, **kw: calls.append((a, kw)) or "S")
    args = _args("--period", "0.001", "--acceleration-limit", "8", "--jerk-limit", "900")
    assert streamed_from_args("PLANNER", args) == "S"
    assert calls == [(("PLANNER", 0.001), {"acceleration_max": 8.0, "jerk_max": 900.0})]


def test_the_summary_line_of_a_stream():
    report = {
        "plan_period_s": 0.02, "plans_used": 99, "plans_refused": 1,
        "planner_step_median_ms": 1.234, "planner_step_max_ms": 5.67,
        "streamer_step_median_us": 12.34, "plan_age_median_ms": 10.4, "plan_age_max_ms": 39.6,
    }  # fmt: skip
    line = stream_summary(report)
    assert line == (
        "plans every 20 ms: 99 used, 1 refused; planner step median 1.23 ms, max 5.7 ms; "
        "streamer step median 12.3 µs; plan age median 10 ms, max 40 ms"
    )
    wall = {**report, "late_commands": 2, "lateness_median_ms": 0.0123,
            "lateness_p99_ms": 0.456, "lateness_max_ms": 1.5, "playout": "playout ok"}  # fmt: skip
    assert stream_summary(wall) == line + (
        "; late commands 2 (lateness median 0.012 ms, p99 0.46 ms, max 1.50 ms); playout ok"
    )


@pytest.mark.parametrize(
    "options",
    [
        ["--plan-period", "0.0015"],
        ["--plan-period", "0.0005"],
        ["--controllers", "local", "--plan-period", "0.01"],
    ],
)
def test_bad_stream_options_exit_2(options, tmp_path, capsys):
    from dqcontrol.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["run", "--period", "0.001", "--controllers", "pf", *options, "--duration",
              "0.5", "--out", str(tmp_path)])  # fmt: skip
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "--plan-period" in err
