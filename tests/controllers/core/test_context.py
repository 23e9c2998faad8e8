"""The step context (:mod:`dqcontrol.controllers.core.context`): the sign-aligned kinematics
against single calls of the model and the trajectory, ``align_into`` against numpy (also on
poses that are views beside their Jacobians, as a batch gives them), and ``qd_now``."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.context import StepContext, align_into, aligned_kinematics
from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.trajectories import Circle


def test_align_into_flips_where_the_product_is_negative():
    rng = np.random.default_rng(2)
    poses, jacobians, targets = (rng.standard_normal((9, 8)), rng.standard_normal((9, 8, 7)),
                                 rng.standard_normal((9, 8)))  # fmt: skip
    sign = np.where(np.einsum("ik,ik->i", poses, targets) < 0.0, -1.0, 1.0)
    assert (sign < 0).any() and (sign > 0).any()
    want_poses, want_jacobians = poses * sign[:, None], jacobians * sign[:, None, None]
    align_into(poses, jacobians, targets)
    np.testing.assert_array_equal(poses, want_poses)
    np.testing.assert_array_equal(jacobians, want_jacobians)
    assert np.all(np.einsum("ik,ik->i", poses, targets) >= 0.0)


def test_align_into_negates_the_poses_on_the_far_side():
    rng = np.random.default_rng(3)
    wide = rng.normal(size=(6, 8 + 8 * 7))  # poses beside their Jacobians, as a batch gives
    xs, jacs = wide[:, :8], wide[:, 8:].reshape(6, 8, 7)
    xd = xs + rng.normal(scale=0.1, size=(6, 8))
    xd[::2] *= -1.0
    flip = np.einsum("pk,pk->p", xs, xd) < 0.0
    assert flip.any() and not flip.all()
    expected = (np.where(flip[:, None], -xs, xs), np.where(flip[:, None, None], -jacs, jacs))
    align_into(xs, jacs, xd)
    assert np.array_equal(xs, expected[0]) and np.array_equal(jacs, expected[1])


def test_aligned_kinematics_are_the_single_calls_with_the_signs_aligned(lbr4p):
    traj = Circle(2.0, reference=np.array([1.0, 0, 0, 0, 0, 0.05, -0.1, 0.2]))
    q_lin = lbr4p.random_configurations(6, seed=4)
    sigma_lin = np.linspace(0.0, 1.5, 6)
    xs, jacs, xd, dxd = aligned_kinematics(lbr4p, traj, q_lin, sigma_lin)
    for i in range(6):
        x, jac = lbr4p.pose_and_jacobian(q_lin[i])
        np.testing.assert_allclose(xd[i], traj.target(sigma_lin[i]), rtol=0, atol=1e-14)
        np.testing.assert_allclose(dxd[i], traj.target_derivative(sigma_lin[i]), atol=1e-14)
        sign = -1.0 if x @ xd[i] < 0.0 else 1.0
        np.testing.assert_allclose(xs[i], sign * x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jacs[i], sign * jac, rtol=0, atol=1e-12)
    assert np.all(np.einsum("ik,ik->i", xs, xd) >= 0.0)


@pytest.mark.parametrize("measured", [False, True])
def test_qd_now_is_the_measurement_where_given(measured):
    layout = DecisionLayout(3, np.zeros(1), np.full(1, 0.01))
    qd_prev, qd_measured = np.array([0.1, 0.2, 0.3]), np.array([-1.0, 0.0, 1.0])
    ctx = StepContext(None, None, layout, 0.01, np.zeros(3), qd_prev, 0.0, None, None, None,
                      None, None, None, qd_measured=qd_measured if measured else None)  # fmt: skip
    assert ctx.qd_now is (qd_measured if measured else qd_prev)
