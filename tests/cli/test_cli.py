"""The ``dqcontrol`` command: ``run`` and ``view`` in short mode (in-process through
``dqcontrol.cli.main``), ``--help`` everywhere, bad options → a clear message and exit
code 2, and ``bench`` without a source checkout → a clear message and exit code 1."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from dqcontrol.cli import build_parser, main
from dqcontrol.runs.storage import load_run
from dqcontrol.viz.figures import FIGURES


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    """``dqcontrol run --short``: the README's first command, in CI's fast mode."""
    out = tmp_path_factory.mktemp("results")
    code = main(["run", "--short", "--out", str(out)])
    return code, out / "lbr4p_circle_T2s_mujoco"


def test_run_writes_runs_figures_replays_and_comparison(default_run, capsys):
    code, folder = default_run
    assert code == 0
    for label in ("local", "p10", "pf"):
        log, record = load_run(folder / f"{label}.npz")
        assert record["metrics"]["completed"]
        assert log.meta["robot"] == "lbr4p" and log.meta["trajectory"] == "circle"
        assert log.meta["simulator"] == "mujoco" and log.meta["label"] == label
        np.testing.assert_allclose(log.meta["velocity_limits"][4], 2.5 * np.pi)
        for figure in FIGURES:  # MuJoCo runs have torques: every figure
            path = folder / f"{label}_{figure}.png"
            assert path.stat().st_size > 3000, path
        html = folder / f"{label}_replay.html"
        assert html.stat().st_size > 500_000  # meshcat's JavaScript is inlined
    assert (folder / "comparison.png").stat().st_size > 10_000
    assert json.loads((folder / "p10.json").read_text())["meta"]["horizon_s"] == 1.0
    pf = json.loads((folder / "pf.json").read_text())["meta"]
    # each controller's own acceleration bound: the thesis's for the thesis's controllers,
    # the dynamics-aware one for path following
    assert pf["controller"] == "path_following" and pf["acceleration_limit"] == "dynamics"
    assert json.loads((folder / "p10.json").read_text())["meta"]["acceleration_limit"] == 10.0
    assert pf["radius_m"] == 0.1  # the trajectory's own metadata


def test_an_acceleration_limit_given_bounds_every_controller(tmp_path, capsys, monkeypatch):
    import dqcontrol.viz.figures as figures
    import dqcontrol.viz.meshcat_viewer as viewer

    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    monkeypatch.setattr(viewer, "export_replay_html", lambda *a, path_points, **k: a[2])
    code = main(
        ["run", "--short", "--simulator", "kinematic", "--controllers", "local,pf",
         "--duration", "4", "--acceleration-limit", "5", "--out", str(tmp_path)]
    )  # fmt: skip
    capsys.readouterr()
    assert code == 0
    folder = tmp_path / "lbr4p_circle_T4s_kinematic"
    for label in ("local", "pf"):
        log, record = load_run(folder / f"{label}.npz")
        assert log.meta["acceleration_limit"] == 5.0
        assert record["metrics"]["acceleration_violations"] == 0
        # the joint accelerations between samples stay within the 5 rad/s² asked for
        qd = np.asarray(log.qd_command)
        assert np.abs(np.diff(qd, axis=0)).max() / 0.05 <= 5.0 + 1e-6


def test_run_compares_local_p10_and_path_following(tmp_path, capsys, monkeypatch):
    import dqcontrol.viz.figures as figures
    import dqcontrol.viz.meshcat_viewer as viewer

    # the outputs are tested above; here the controllers, the table and the saved runs
    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    monkeypatch.setattr(viewer, "export_replay_html", lambda *a, path_points, **k: a[2])
    code = main(
        ["run", "--short", "--simulator", "kinematic", "--controllers", "local,p10,path-following",
         "--duration", "1", "--out", str(tmp_path)]
    )  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0
    rows = {line.split()[0]: line.split() for line in out.splitlines() if line.split()[:1] in (
        ["local"], ["p10"], ["pf"])}  # fmt: skip
    assert set(rows) == {"local", "p10", "pf"} and all(r[1] == "yes" for r in rows.values())
    dev_mm = {name: float(r[5]) for name, r in rows.items()}  # the dev_mm column
    assert dev_mm["pf"] < 0.5 < min(dev_mm["local"], dev_mm["p10"])
    folder = tmp_path / "lbr4p_circle_T1s_kinematic"
    log, record = load_run(folder / "pf.npz")
    assert record["metrics"]["completed"] and log.meta["label"] == "pf"


def test_run_prints_a_metrics_table(tmp_path, capsys):
    code = main(
        ["run", "--short", "--simulator", "kinematic", "--controllers", "proportional,p3",
         "--duration", "1", "--out", str(tmp_path)]
    )  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0
    lines = out.splitlines()
    header = next(line for line in lines if line.startswith("controller"))
    assert "e_mean" in header and "s_mean" in header and "viol" in header
    rows = {line.split()[0]: line.split() for line in lines if line.split()[:1] in (
        ["proportional"], ["p3"])}  # fmt: skip
    assert set(rows) == {"proportional", "p3"} and rows["p3"][1] == "yes"
    folder = tmp_path / "lbr4p_circle_T1s_kinematic"
    assert not list(folder.glob("*_joint_torques.png"))  # the kinematic loop has none
    assert (folder / "comparison.png").is_file()


def test_run_at_one_kilohertz(tmp_path, capsys, monkeypatch):
    """``--period 0.001`` (the 1 kHz demo) goes through MuJoCo's 1 ms physics step."""
    import dqcontrol.viz.figures as figures
    import dqcontrol.viz.meshcat_viewer as viewer

    # the outputs are tested above; here only the loop at T = 1 ms
    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    monkeypatch.setattr(viewer, "export_replay_html", lambda *a, path_points, **k: a[2])
    code = main(
        ["run", "--short", "--period", "0.001", "--duration", "0.3", "--controllers", "local",
         "--out", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    log, record = load_run(tmp_path / "lbr4p_circle_T0.3s_mujoco" / "local.json")
    assert log.meta["period_s"] == 0.001 and record["metrics"]["completed"]
    assert len(log) >= 300  # σ advances by at most T per sample (s ≤ 1)
    np.testing.assert_allclose(np.diff(log.t_s), 0.001, atol=1e-9)


def test_view_rewrites_replay_and_figures(default_run, tmp_path, capsys):
    _, folder = default_run
    code = main(["view", str(folder / "p10.npz"), "--html", "--figures", "--out", str(tmp_path)])
    assert code == 0
    assert (tmp_path / "p10_replay.html").stat().st_size > 500_000
    assert len(list(tmp_path.glob("p10_*.png"))) == len(FIGURES)
    assert "wrote" in capsys.readouterr().out


def test_view_replays_in_the_live_viewer(default_run, capsys):
    _, folder = default_run
    code = main(["view", str(folder / "local.json"), "--hold", "0", "--speed", "2"])
    out = capsys.readouterr().out
    assert code == 0
    assert "Meshcat viewer: http://127.0.0.1:" in out and "replaying local" in out


def test_every_subcommand_has_help(capsys):
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    assert {"run", "view"} <= set(commands)
    for name in commands:
        with pytest.raises(SystemExit) as exc:
            main([name, "--help"])
        assert exc.value.code == 0
        assert f"usage: dqcontrol {name}" in capsys.readouterr().out


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


def test_unknown_controller_lists_the_known_ones(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--controllers", "mpc"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    for known in ("local", "p10", "noscale", "proportional", "pf", "path-following"):
        assert known in err, known


def test_bench_needs_a_source_checkout(tmp_path, monkeypatch, capsys):
    from dqcontrol.cli import bench_cmd

    assert bench_cmd.bench_path().is_file()  # this checkout has it
    monkeypatch.setattr(bench_cmd, "bench_path", lambda: tmp_path / "benchmarks" / "bench.py")
    monkeypatch.delitem(__import__("sys").modules, bench_cmd._MODULE, raising=False)
    assert main(["bench", "--quick", "--out", str(tmp_path / "bench.json")]) == 1
    err = capsys.readouterr().err
    assert "needs a source checkout" in err and "Traceback" not in err
    assert not (tmp_path / "bench.json").exists()


def test_view_with_nothing_to_do_exits_2(default_run, capsys):
    _, folder = default_run
    with pytest.raises(SystemExit) as exc:
        main(["view", str(folder / "p10.npz"), "--no-viewer"])
    assert exc.value.code == 2
    assert "nothing to do" in capsys.readouterr().err


class _Log:
    def __init__(self, sigma: list[float], s: list[float]) -> None:
        self.sigma, self.s = np.array(sigma), np.array(s)

    def __len__(self) -> int:
        return self.sigma.size


def _result(log: _Log, interrupted: bool = False, note: str = ""):
    from dqcontrol.sim.loop import RunResult

    return RunResult(log, None, interrupted, note)  # type: ignore[arg-type]


def test_an_incomplete_run_says_where_and_why_it_stopped():
    from dqcontrol.cli.run_cmd import _stop
    from dqcontrol.trajectories import Circle

    task = Circle(2.0)
    stalled = _stop(_result(_Log([0.0, 1.25], [0.4, 0.0])), task)
    assert stalled == (
        "the phase reached 1.25 s of T_tot = 2 s, where it stopped (s = 0): the path ahead "
        "is out of reach or blocked"
    )
    slow = _stop(_result(_Log([0.0, 1.5], [0.4, 0.3])), task)
    assert slow.endswith("1.5 s of T_tot = 2 s when the run's time limit came")
    cut = _stop(_result(_Log([0.0, 0.5], [0.4, 0.3]), True, "interrupted by the user"), task)
    assert cut.endswith("0.5 s of T_tot = 2 s (interrupted by the user)")
    assert _stop(_result(_Log([], []), True), task) == "the phase reached 0 s of T_tot = 2 s"
