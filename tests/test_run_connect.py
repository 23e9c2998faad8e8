"""``dqcontrol run --connect``: the controller in this process, the simulation behind a
sim-server (here a thread on the loopback address)."""

from __future__ import annotations

import threading

import pytest

from dqcontrol.cli import main
from dqcontrol.sim import KinematicDriver
from dqcontrol.sim.bridge import SimServer

pytest.importorskip("zmq")


def _serve(server: SimServer) -> threading.Thread:
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    return thread


def test_run_against_a_sim_server(lbr4p, tmp_path, capsys):
    server = SimServer(KinematicDriver(lbr4p, 0.05))
    thread = _serve(server)
    try:
        code = main([
            "run", "--connect", server.address, "--controllers", "local", "--duration", "2",
            "--out", str(tmp_path), "--short", "--no-viewer",
        ])  # fmt: skip
    finally:
        server.stop()
        thread.join(5.0)
        server.close()
    out = capsys.readouterr().out
    assert code == 0
    assert "local" in out and "yes" in out  # the run completed


def test_a_period_that_differs_from_the_servers_is_refused(lbr4p, tmp_path, capsys):
    server = SimServer(KinematicDriver(lbr4p, 0.01))
    thread = _serve(server)
    try:
        code = main([
            "run", "--connect", server.address, "--controllers", "local", "--period", "0.05",
            "--out", str(tmp_path), "--short", "--no-viewer",
        ])  # fmt: skip
    finally:
        server.stop()
        thread.join(5.0)
        server.close()
    assert code != 0
    assert "--period 0.01" in capsys.readouterr().err
