"""``robot.fast`` (``dqcontrol.model.fast``): each unchecked call against the checked ``RobotModel``
method and Pinocchio's algorithms, the batched acceleration bound against ``M(q)``, ``g(q)``."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0


@pytest.mark.parametrize(("fraction", "floor", "cap"), [(1.0, 0.5, 50.0), (0.6, 2.0, 8.0)])
def test_the_batch_is_each_configurations_bound(lbr4p, fraction, floor, cap):
    qs = LBR4P_Q0 + np.random.default_rng(3).uniform(-0.8, 0.8, (6, lbr4p.nq))
    batch = lbr4p.fast.acceleration_limits_batch(qs, fraction, floor, cap)
    rows = [lbr4p.fast.acceleration_limits(q, fraction, floor, cap) for q in qs]
    assert np.array_equal(batch, np.array(rows))
    for q, a in zip(qs, batch, strict=True):
        m, g = lbr4p.mass_matrix(q), lbr4p.gravity(q)
        spare = fraction * lbr4p.limits.effort_max - np.abs(g)
        np.testing.assert_allclose(a, np.clip(spare / np.diag(m), floor, cap), rtol=1e-12)
    assert (batch > floor).any() and (batch <= cap).all()


def test_the_batch_checks_its_settings(lbr4p):
    qs = np.tile(LBR4P_Q0, (2, 1))
    with pytest.raises(ParameterError, match="effort_fraction"):
        lbr4p.fast.acceleration_limits_batch(qs, 1.5, 0.5, 50.0)
    with pytest.raises(ParameterError, match="floor_rad_s2"):
        lbr4p.fast.acceleration_limits_batch(qs, 1.0, 5.0, 1.0)


def _configurations(robot, seed: int) -> np.ndarray:
    return robot.random_configurations(5, seed=seed)


def test_kinematics_equal_the_checked_calls(lbr4p, panda):
    for robot in (lbr4p, panda):
        qs = _configurations(robot, seed=31)
        for q in qs:
            x, jac = robot.fast.pose_and_jacobian(q)
            x_ref, jac_ref = robot.pose_and_jacobian(q)
            np.testing.assert_array_equal(x, x_ref)
            np.testing.assert_array_equal(jac, jac_ref)
            np.testing.assert_array_equal(robot.fast.pose(q), robot.pose(q))
        xs, jacs = robot.fast.poses_and_jacobians(qs)
        xs_ref, jacs_ref = robot.poses_and_jacobians(qs)
        np.testing.assert_array_equal(xs, xs_ref)
        np.testing.assert_array_equal(jacs, jacs_ref)
        # the closed-form batch agrees with the single poses to rounding (docstring)
        np.testing.assert_allclose(robot.fast.poses(qs), xs_ref, rtol=0, atol=1e-12)


def test_mass_matrix_and_gravity_are_pinocchios(lbr4p):
    data = lbr4p.model.createData()
    zero = np.zeros(lbr4p.nq)
    for q in _configurations(lbr4p, seed=32):
        m, g = lbr4p.fast.mass_gravity(q)
        np.testing.assert_array_equal(m, m.T)  # the full matrix, not crba's upper triangle
        np.testing.assert_allclose(m, lbr4p.mass_matrix(q), rtol=0, atol=1e-12)
        np.testing.assert_allclose(g, pin.rnea(lbr4p.model, data, q, zero, zero), atol=1e-12)


def test_bias_forces_are_the_inverse_dynamics_at_zero_acceleration(lbr4p):
    data = lbr4p.model.createData()
    rng = np.random.default_rng(33)
    for q in _configurations(lbr4p, seed=34):
        qd = rng.uniform(-1.0, 1.0, lbr4p.nq)
        expected = pin.rnea(lbr4p.model, data, q, qd, np.zeros(lbr4p.nq))
        np.testing.assert_allclose(lbr4p.fast.bias_forces(q, qd), expected, rtol=0, atol=1e-12)


def test_results_are_fresh_arrays(lbr4p):
    q = LBR4P_Q0.copy()
    x = lbr4p.fast.pose(q)
    x[:] = 0.0
    assert np.any(lbr4p.fast.pose(q) != 0.0)
    m, g = lbr4p.fast.mass_gravity(q)
    m[:] = 0.0
    g[:] = 0.0
    m2, g2 = lbr4p.fast.mass_gravity(q)
    assert np.any(m2 != 0.0) and np.any(g2 != 0.0)


def test_pose_and_jacobian_into_writes_what_the_call_returns(lbr4p, panda):
    rng = np.random.default_rng(11)
    for robot in (lbr4p, panda):
        x, jac = np.full(8, np.nan), np.full((8, robot.nq), np.nan)
        for _ in range(20):
            q = rng.uniform(robot.limits.q_min, robot.limits.q_max)
            robot.fast.pose_and_jacobian_into(q, x, jac)
            x_new, jac_new = robot.fast.pose_and_jacobian(q)
            assert np.array_equal(x, x_new) and np.array_equal(jac, jac_new)


def test_the_one_block_controllers_report_a_new_pose_each_step(lbr4p):
    from dqcontrol.controllers import LocalController, ProportionalController
    from dqcontrol.trajectories import Circle

    for cls in (LocalController, ProportionalController):
        controller = cls(lbr4p, Circle(1.0), 0.01)
        controller.reset(LBR4P_Q0)
        q = np.array(LBR4P_Q0, dtype=float)
        first = controller.step(q)
        kept = first.pose.copy()
        second = controller.step(q + 0.01 * first.qd_command)
        assert second.pose is not first.pose and np.array_equal(first.pose, kept)
