"""``dqcontrol run`` (dqcontrol/cli/run_cmd.py): whole runs in short mode (in-process through
``dqcontrol.cli.main``), the checks of its options that need the robot, obstacles from the
command line, ``--connect`` to a sim-server, where an incomplete run stopped, the log streamed
beside the saved run, and a log that cannot be written → exit code 1 with a clear message."""

from __future__ import annotations

import base64
import importlib.util
import json
import re
import threading

import numpy as np
import pytest
import umsgpack
from runs.test_mcap_log import _failing_sync

from dqcontrol import __version__
from dqcontrol.cli import main
from dqcontrol.runs.mcap_log import McapRunWriter
from dqcontrol.runs.storage import load_run
from dqcontrol.sim import KinematicDriver
from dqcontrol.viz.figures import FIGURES

#: A ball on the circle's path at σ = 1 s (the circle at 2 s from the LBR4p's start posture).
BALL = "sphere:0.4865,-0.3922,0.7006,0.03"

needs_zmq = pytest.mark.skipif(
    importlib.util.find_spec("zmq") is None, reason="the sim-server bridge needs pyzmq"
)


def _bad(argv: list[str], capsys) -> str:
    """Run ``argv``, expect exit code 2 and return stderr."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert re.search(rf"^dqcontrol {argv[0]}: error: ", err, re.MULTILINE), err
    assert "Traceback" not in err
    return err


# ---------------------------------------------------------------------- whole runs
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


# ---------------------------------------------------------------------- the options' checks
def test_thesis_velocity_limits_need_all_seven_joints(capsys):
    err = _bad(["run", "--lock", "lbr4p_joint_7=0", "--velocity-limits", "thesis"], capsys)
    assert "this robot has 6 joints" in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--realtime"], "--realtime keeps the wall clock against a sim-server: give --connect"),
        (["--max-lateness", "0.1"], "--max-lateness applies to a wall-clock run: give --realtime"),
        (["--rt-priority", "10"], "--rt-priority applies to a wall-clock run: give --realtime"),
        (["--velocity-limits", "1,-2"], "--velocity-limits: give 1 or 7 values > 0 [rad/s]"),
        (["--velocity-limits", "fast"], "--velocity-limits: 'thesis', 'urdf' or numbers"),
    ],
)
def test_wall_clock_and_bound_options_are_checked_before_any_run(argv, message, capsys, tmp_path):
    err = _bad(["run", "--simulator", "kinematic", *argv, "--out", str(tmp_path / "o")], capsys)
    assert message in err
    assert not (tmp_path / "o").exists()


def test_make_trajectory_is_rebuilt_from_its_meta(lbr4p):
    from dqcontrol.cli.run_cmd import make_trajectory
    from dqcontrol.model import LBR4P_Q0
    from dqcontrol.trajectories import trajectory_from_metadata

    traj, meta = make_trajectory("sinusoid", 4.0)
    assert meta["trajectory"] == "sinusoid" and traj.duration == 4.0
    again = trajectory_from_metadata(meta)
    assert again.to_metadata() == meta
    x0 = lbr4p.pose(LBR4P_Q0)
    np.testing.assert_allclose(
        again.anchored_at(x0).path_positions(50), traj.anchored_at(x0).path_positions(50),
        atol=1e-12,
    )  # fmt: skip


def test_trajectory_from_meta_is_none_without_samples_or_a_task(default_run):
    from dqcontrol.cli.run_cmd import trajectory_from_meta

    _, folder = default_run
    log, _record = load_run(folder / "local.npz")
    traj = trajectory_from_meta(log.meta, log)
    assert traj is not None and traj.duration == 2.0
    # anchored where the run's first target was
    np.testing.assert_allclose(traj.target(0.0), log.target[0], atol=1e-9)
    assert trajectory_from_meta({"trajectory": "square"}, log) is None
    assert trajectory_from_meta(log.meta, log.__class__.from_arrays(
        {k: v[:0] for k, v in log.arrays().items()}, log.meta)) is None  # fmt: skip


# ---------------------------------------------------------------------- where a run stopped
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


# ---------------------------------------------------------------------- obstacles
@pytest.mark.parametrize(
    ("option", "message"),
    [
        ("cone:1,2,3", "unknown obstacle shape 'cone'"),
        ("sphere:0,0,1,-0.1", "radius_m"),
        ("sphere:nan,0,1,0.1", "position_m must be finite"),
        ("sphere:0,0,inf,0.1", "position_m must be finite"),
        ("box:0,0,1,0.1,0.1", "6 numbers"),
        ("box:0,0,1,0.1,-0.1,0.1", "size_m"),
        ("plane:0,0,0,0.3", "normal"),
        ("capsule:0,0,1,0.1,x", "number"),
    ],
)
def test_bad_obstacles_exit_2(option, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--simulator", "kinematic", "--obstacle", option, "--out", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--obstacle" in err and message in err


def test_a_controller_without_limits_is_refused(capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--controllers", "proportional", "--obstacle", BALL, "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert "takes no limits" in capsys.readouterr().err


def test_run_with_an_obstacle_reports_distance_and_contacts(capsys, tmp_path, monkeypatch):
    import dqcontrol.viz.figures as figures

    # the figures do not draw obstacles and are tested above; here the report, the saved
    # run and the replay (a third of the run's time is the figures)
    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    code = main(
        [
            "run", "--simulator", "kinematic", "--controllers", "pf", "--period", "0.01",
            "--duration", "2", "--obstacle", BALL, "--short", "--out", str(tmp_path),
        ]
    )  # fmt: skip
    assert code == 1  # the path is blocked: the task does not complete
    out, err = capsys.readouterr()
    stop = re.search(r"pf did not complete the trajectory: the phase reached ([\d.]+) s of "
                     r"T_tot = 2 s, where it stopped \(s = 0\)", err)  # fmt: skip
    assert stop is not None, err
    assert 0.5 < float(stop.group(1)) < 1.0  # before the ball, which is on the path at 1 s
    line = re.search(
        r"pf: min distance ([\d.]+) mm; contacts robot-obstacle (\d+), self (\d+)", out
    )
    assert line is not None, out
    assert float(line.group(1)) >= 19.5 and line.group(2) == "0" and line.group(3) == "0"
    folder = tmp_path / "lbr4p_circle_T2s_kinematic"
    meta = json.loads((folder / "pf.json").read_text())
    assert meta["meta"]["obstacles"] == [BALL]
    html = (folder / "pf_replay.html").read_text()
    assert "/meshcat/dqcontrol/obstacles/obstacle1/0" in _object_paths(html)


def _object_paths(html: str) -> set[str]:
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    return {c["path"] for c in cmds if c["type"] == "set_object"}


# ---------------------------------------------------------------------- --connect
def _run_against(server, *options: str) -> int:
    """``dqcontrol run --connect`` against ``server`` served by a thread; the exit code."""
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    try:
        return main(["run", "--connect", server.address, "--short", "--no-viewer", *options])
    finally:
        server.stop()
        thread.join(5.0)
        server.close()


@needs_zmq
def test_run_against_a_sim_server(lbr4p, tmp_path, capsys):
    from dqcontrol.sim.bridge import SimServer

    server = SimServer(KinematicDriver(lbr4p, 0.05))
    code = _run_against(server, "--controllers", "local", "--duration", "2", "--out", str(tmp_path))
    out = capsys.readouterr().out
    assert code == 0
    assert "local" in out and "yes" in out  # the run completed


@needs_zmq
def test_a_period_that_differs_from_the_servers_is_refused(lbr4p, tmp_path, capsys):
    from dqcontrol.sim.bridge import SimServer

    server = SimServer(KinematicDriver(lbr4p, 0.01))
    code = _run_against(
        server, "--controllers", "local", "--period", "0.05", "--out", str(tmp_path)
    )
    assert code != 0
    assert "--period 0.01" in capsys.readouterr().err


@needs_zmq
def test_the_servers_description_is_in_the_saved_run_and_in_view(lbr4p, tmp_path, capsys):
    from dqcontrol.sim.bridge import SimServer

    server = SimServer(KinematicDriver(lbr4p, 0.05), description={"robot": "lbr4p-test"})
    code = _run_against(server, "--controllers", "local", "--duration", "1", "--out", str(tmp_path))
    assert code == 0
    (saved,) = tmp_path.glob("**/local.json")
    log, record = load_run(saved)
    described = record["meta"]["server"]
    assert described == log.meta["server"]
    assert described["server"] == "dqcontrol sim-server"
    assert described["dqcontrol_version"] == __version__ and described["protocol_version"] == 1
    assert described["simulator"] == "kinematic" and described["period_s"] == 0.05
    assert described["joint_names"] == list(lbr4p.joint_names)
    assert described["robot"] == "lbr4p-test"
    assert record["meta"]["simulator"] == "bridge" and record["meta"]["address"] == server.address
    capsys.readouterr()
    assert main(["view", str(saved), "--figures", "--no-viewer", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"dqcontrol sim-server {__version__} at {server.address}: lbr4p-test, kinematic" in out


# ---------------------------------------------------------------------- the streamed log
_CLI = ["run", "--short", "--simulator", "kinematic", "--controllers", "local",
        "--duration", "0.5"]  # fmt: skip


def _no_figures(monkeypatch) -> None:
    """Figures and replays off (tested elsewhere): only the run and its files here."""
    import dqcontrol.viz.figures as figures
    import dqcontrol.viz.meshcat_viewer as viewer

    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    monkeypatch.setattr(viewer, "export_replay_html", lambda *a, path_points, **k: a[2])


def test_cli_full_disk_exits_1_with_a_clear_message(tmp_path, capsys, monkeypatch):
    _no_figures(monkeypatch)
    monkeypatch.setattr(McapRunWriter, "_sync", _failing_sync(after=2))
    code = main([*_CLI, "--period", "0.001", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 1
    assert "cannot write the run log" in err and "No space left on device" in err
    assert "Traceback" not in err


def test_cli_unwritable_folder_exits_1_with_a_clear_message(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    code = main([*_CLI, "--out", str(blocker)])
    err = capsys.readouterr().err
    assert code == 1 and "cannot write the run log" in err and "Traceback" not in err


def test_cli_read_only_folder_exits_1(tmp_path, capsys):
    import os

    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders")
    tmp_path.chmod(0o500)
    try:
        code = main([*_CLI, "--out", str(tmp_path)])
    finally:
        tmp_path.chmod(0o700)
    assert code == 1 and "cannot write the run log" in capsys.readouterr().err


def test_cli_streams_the_log_beside_the_saved_run(tmp_path, monkeypatch):
    _no_figures(monkeypatch)
    assert main([*_CLI, "--out", str(tmp_path)]) == 0
    folder = tmp_path / "lbr4p_circle_T0.5s_kinematic"
    streamed, _ = load_run(folder / "local.mcap")
    saved, record = load_run(folder / "local.json")
    assert record["log"] == "local.mcap" and record["npz"] == "local.npz"
    np.testing.assert_array_equal(streamed.q, saved.q)
