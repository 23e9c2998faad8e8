"""The singularity damping's weight (dqcontrol/controllers/terms/singularity_damping.py,
docs/theory.md §8.3) against the SVD of ``E J``, on both sides of the threshold."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.step_contexts import random_context

from dqcontrol.controllers.terms.path_error import tangent_projectors
from dqcontrol.controllers.terms.singularity_damping import SingularityDampingTerm


def pose_and_jacobian(rng, singular_values: np.ndarray, n: int):
    """A unit pose and a Jacobian ``(8, n)`` whose ``E J`` has these singular values."""
    x = rng.normal(size=8)
    x[:4] /= np.linalg.norm(x[:4])
    x[4:] -= (x[4:] @ x[:4]) * x[:4]  # a unit dual quaternion
    e = tangent_projectors(x[None, :])[0]
    k = singular_values.size
    u = np.linalg.qr(rng.normal(size=(6, 6)))[0][:, :k]
    v = np.linalg.qr(rng.normal(size=(n, n)))[0][:, :k]
    tangent = (u * singular_values) @ v.T
    return x, np.linalg.pinv(e) @ tangent


def smallest_singular_value(x, jac) -> float:
    """The smallest singular value of ``E J`` by numpy's SVD."""
    return float(np.linalg.svd(tangent_projectors(x[None, :])[0] @ jac, compute_uv=False)[-1])


@pytest.mark.parametrize("ratio", [0.0, 0.5, 0.9, 0.999, 1.001, 2.0])
def test_the_weight_is_that_of_the_smallest_singular_value(lbr4p, ratio):
    ctx = random_context(lbr4p, 3, seed=4)
    rng = np.random.default_rng(11)
    values = np.array([1.2, 1.0, 0.8, 0.6, 0.4, 0.04 * ratio])
    x, jac = pose_and_jacobian(rng, values, lbr4p.nq)
    ctx.poses[0], ctx.jacobians[0] = x, jac
    term = SingularityDampingTerm(ctx.layout, 0.04, 0.05, 7.0)
    assert term.sigma_min == np.inf  # before a step
    res = term.residual(ctx)
    sigma = smallest_singular_value(x, jac)
    r = sigma / 0.04
    expected = 7.0 * (0.05**2 * (1.0 - r * r)) if r < 1.0 else 0.0
    assert res.weight == expected and term.weight == expected
    assert term.sigma_min == sigma
    assert term.residual(ctx) is not res and term.residual(ctx).weight == expected
