"""Computed torque in MuJoCo (``motor="torque"``): tracking, effort limits, the ramp."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim import MujocoDriver, MujocoSimulation, run_loop
from dqcontrol.trajectories import Circle


def _velocity_error_rms(log) -> float:
    """RMS of ``qd`` measured at sample k+1 minus the command of period k [rad/s]."""
    return float(np.sqrt(np.mean((log.qd_measured[1:] - log.qd_command[:-1]) ** 2)))


def test_computed_torque_tracks_the_velocity_better_than_the_servo_within_the_limits(lbr4p):
    runs = {}
    for motor in ("velocity", "torque"):
        driver = MujocoDriver(lbr4p, 0.05, motor=motor)
        res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), driver, q0=LBR4P_Q0)
        assert res.metrics.completed and res.log.meta["motor"] == motor
        limit = driver.simulation.torque_limit
        assert (res.log.torque_peak <= limit + 1e-9).all()
        runs[motor] = res
    servo, ct = (_velocity_error_rms(runs[m].log) for m in ("velocity", "torque"))
    assert ct < 0.1 * servo
    assert runs["torque"].metrics.torque_peak_nm < runs["velocity"].metrics.torque_peak_nm


def test_the_ramp_reaches_the_command_at_the_end_of_the_step(lbr4p):
    u = np.array([0.3, -0.2, 0.25, 0.3, -0.4, 0.5, 0.6])
    sim2 = MujocoSimulation(lbr4p, motor="torque", command_ramp_s=0.05)
    sim2.reset(LBR4P_Q0)
    mid = sim2.step(u, 0.025)  # half-way along a 50 ms ramp
    np.testing.assert_allclose(mid.qd, 0.5 * u, atol=2e-3)
    end = sim2.step(u, 0.025)  # the same command: the ramp goes on
    np.testing.assert_allclose(end.qd, u, atol=2e-3)
    later = sim2.step(u, 0.05)
    np.testing.assert_allclose(later.qd, u, atol=2e-3)


def test_an_impossible_step_is_clipped_to_the_effort_limits(lbr4p):
    sim = MujocoSimulation(lbr4p, motor="torque", effort_scale=0.5)
    sim.reset(LBR4P_Q0)
    peak = np.zeros(7)
    for _ in range(20):
        peak = np.maximum(peak, sim.step(np.full(7, 3.0), 0.01).torque_peak)
    assert (peak <= sim.torque_limit + 1e-9).all() and (peak >= sim.torque_limit - 1e-9).any()


def test_an_unknown_payload_leaves_a_velocity_error(lbr4p):
    sim = MujocoSimulation(lbr4p, motor="torque", payload_kg=3.0)
    sim.reset(LBR4P_Q0)
    for _ in range(10):
        m = sim.step(np.zeros(7), 0.05)
    assert np.abs(m.qd).max() > 1e-3  # no integral action: the payload's torque shows


def test_bad_computed_torque_options(lbr4p):
    with pytest.raises(ParameterError, match="motor must be one of"):
        MujocoSimulation(lbr4p, motor="current")
    with pytest.raises(ParameterError, match="command_ramp_s must be finite"):
        MujocoSimulation(lbr4p, motor="torque", command_ramp_s=-1.0)
    sim = MujocoSimulation(lbr4p, motor="torque", command_ramp_s=0.0015)
    sim.reset(LBR4P_Q0)
    with pytest.raises(ParameterError, match="not a whole number of physics steps"):
        sim.step(np.ones(7), 0.01)


def test_the_comparison_script_runs_short(capsys):
    import runpy
    from pathlib import Path

    script = Path(__file__).resolve().parents[2] / "docs" / "drivers_comparison.py"
    main = runpy.run_path(str(script), run_name="drivers_comparison")["main"]
    assert main(["--short"]) == 0
    out = capsys.readouterr().out
    assert "| circle 1 s | local | computed torque | 0 | yes |" in out
