"""The servo identification: a first-order lag fitted to measured velocities."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.sim.driver import KinematicDriver
from dqcontrol.sim.servo_identification import (
    identify_servo_time_constant,
    stated_servo_time_constant,
)


def _lag_response(tau_s: float, period_s: float, commands: np.ndarray, noise: float, seed: int):
    """The exact response of a first-order lag to held commands, with measurement noise."""
    rng = np.random.default_rng(seed)
    alpha = 1.0 - math.exp(-period_s / tau_s) if tau_s > 0 else 1.0
    qd = np.zeros((commands.shape[0] + 1, commands.shape[1]))
    for k, u in enumerate(commands):
        qd[k + 1] = qd[k] + alpha * (u - qd[k])
    return qd + noise * rng.standard_normal(qd.shape)


@pytest.mark.parametrize(("tau_s", "period_s"), [(0.005, 0.001), (0.005, 0.01), (0.03, 0.01)])
def test_the_time_constant_of_a_simulated_lag_is_recovered(tau_s, period_s):
    rng = np.random.default_rng(3)
    commands = rng.uniform(-1.0, 1.0, (40, 7))
    qd = _lag_response(tau_s, period_s, commands, 0.0, 0)
    fit = identify_servo_time_constant(qd, commands, period_s)
    assert fit.time_constant_s == pytest.approx(tau_s, rel=1e-9)
    assert fit.residual_rad_s < 1e-12
    assert fit.samples == 40 * 7


def test_noise_moves_the_estimate_little():
    rng = np.random.default_rng(5)
    commands = rng.uniform(-1.0, 1.0, (200, 6))
    qd = _lag_response(0.02, 0.01, commands, 1e-3, 1)
    fit = identify_servo_time_constant(qd, commands, 0.01)
    assert fit.time_constant_s == pytest.approx(0.02, rel=0.02)
    assert fit.residual_rad_s == pytest.approx(math.sqrt(2) * 1e-3 * 1.2, rel=0.5)


def test_a_servo_that_settles_within_a_period_is_ideal():
    commands = np.random.default_rng(2).uniform(-1.0, 1.0, (10, 3))
    qd = np.vstack((np.zeros(3), commands))  # qd(k+1) = u_k
    fit = identify_servo_time_constant(qd, commands, 0.05)
    assert fit.time_constant_s == 0.0
    assert fit.step_fraction == 1.0


def test_the_fit_refuses_what_it_cannot_identify():
    with pytest.raises(ParameterError, match="hardly differ"):
        identify_servo_time_constant(np.zeros((4, 2)), np.zeros((3, 2)), 0.01)
    with pytest.raises(ParameterError, match=r"\(K \+ 1, n\)"):
        identify_servo_time_constant(np.zeros((3, 2)), np.zeros((3, 2)), 0.01)
    with pytest.raises(ParameterError, match="did not follow"):
        identify_servo_time_constant(np.zeros((4, 2)), np.ones((3, 2)), 0.01)
    with pytest.raises(ParameterError, match="period_s"):
        identify_servo_time_constant(np.zeros((4, 2)), np.ones((3, 2)), 0.0)


def test_the_servo_of_the_mujoco_simulation_is_identified_from_its_response(lbr4p):
    pytest.importorskip("mujoco")
    from dqcontrol.sim.mujoco_sim import SERVO_TIME_CONSTANT_S, MujocoSimulation

    sim = MujocoSimulation(lbr4p)
    sim.reset(LBR4P_Q0)
    period = 0.002
    commands = 0.05 * np.sin(np.arange(30)[:, None] * 0.4 + np.arange(7)[None, :])
    qd = [sim.measure().qd.copy()]
    for u in commands:
        qd.append(sim.step(u, period).qd.copy())
    fit = identify_servo_time_constant(np.array(qd), commands, period)
    # the servo is a first-order lag of τ_v with the nominal model (module docstring of
    # mujoco_sim); the integral action and the unmodelled damping move it a little
    assert fit.time_constant_s == pytest.approx(SERVO_TIME_CONSTANT_S, rel=0.2)
    assert stated_servo_time_constant(sim) == SERVO_TIME_CONSTANT_S


def test_the_kinematic_loop_states_ideal_tracking(lbr4p):
    assert stated_servo_time_constant(KinematicDriver(lbr4p, 0.01)) == 0.0
    assert stated_servo_time_constant(object()) is None
