"""The jerk-limited braking law (dqcontrol/sim/jerk_brake.py), checked on its commands'
finite differences: every one within the acceleration and jerk bounds, the velocities
keeping their direction once the acceleration is turned, and 0 reached."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.sim.jerk_brake import jerk_brake_command

T = 1e-3
A_MAX = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
J_MAX = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0])


def _brake(u1, u2, steps: int = 400) -> np.ndarray:
    """The commands ``u2, u1, …`` of ``steps`` periods of the law."""
    out = [u2, u1]
    for _ in range(steps):
        out.append(jerk_brake_command(out[-1], out[-2], A_MAX, J_MAX, T))
    return np.array(out)


@pytest.mark.parametrize("seed", range(5))
def test_every_command_keeps_the_acceleration_and_jerk_bounds(seed):
    rng = np.random.default_rng(seed)
    u1 = rng.uniform(-0.5, 0.5, 7)
    accel = rng.uniform(-0.5, 0.5, 7) * A_MAX  # a feasible start: half the bound at most
    commands = _brake(u1, u1 - T * accel)
    a = np.diff(commands, axis=0) / T
    j = np.diff(a, axis=0) / T
    assert np.all(np.abs(a) <= A_MAX * (1 + 1e-9))
    assert np.all(np.abs(j) <= J_MAX * (1 + 1e-9))


@pytest.mark.parametrize("seed", range(5))
def test_it_comes_to_rest_within_a_jerk_step(seed):
    rng = np.random.default_rng(100 + seed)
    u1 = rng.uniform(-0.5, 0.5, 7)
    commands = _brake(u1, u1.copy(), steps=2000)
    assert np.all(np.abs(commands[-1]) <= J_MAX * T * T)
    assert np.all(np.abs(commands[-1] - commands[-2]) <= J_MAX * T * T)


def test_from_constant_velocity_the_direction_is_kept():
    u1 = np.array([0.3, -0.2, 0.1, 0.0, 0.05, -0.4, 0.2])
    commands = _brake(u1, u1.copy(), steps=30)
    # each command a positive multiple of the first (to rounding) while it still moves
    for u in commands[2:]:
        scale = float(u @ u1) / float(u1 @ u1)
        if scale > 1e-3:
            np.testing.assert_allclose(u, scale * u1, atol=J_MAX.max() * T * T)
