"""``dqcontrol run --connect``: the controller in this process, the simulation behind a
sim-server (here a thread on the loopback address)."""

from __future__ import annotations

import threading

import pytest

from dqcontrol import __version__
from dqcontrol.cli import main
from dqcontrol.runs.storage import load_run
from dqcontrol.sim import KinematicDriver
from dqcontrol.sim.bridge import SimServer

pytest.importorskip("zmq")


def _run_against(server: SimServer, *options: str) -> int:
    """``dqcontrol run --connect`` against ``server`` served by a thread; the exit code."""
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    try:
        return main(["run", "--connect", server.address, "--short", "--no-viewer", *options])
    finally:
        server.stop()
        thread.join(5.0)
        server.close()


def test_run_against_a_sim_server(lbr4p, tmp_path, capsys):
    server = SimServer(KinematicDriver(lbr4p, 0.05))
    code = _run_against(server, "--controllers", "local", "--duration", "2", "--out", str(tmp_path))
    out = capsys.readouterr().out
    assert code == 0
    assert "local" in out and "yes" in out  # the run completed


def test_a_period_that_differs_from_the_servers_is_refused(lbr4p, tmp_path, capsys):
    server = SimServer(KinematicDriver(lbr4p, 0.01))
    code = _run_against(
        server, "--controllers", "local", "--period", "0.05", "--out", str(tmp_path)
    )
    assert code != 0
    assert "--period 0.01" in capsys.readouterr().err


def test_the_servers_description_is_in_the_saved_run_and_in_view(lbr4p, tmp_path, capsys):
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
