"""The tracking term (dqcontrol/controllers/terms/tracking.py) against an independent numpy
computation (docs/theory.md §4.2, §7.3): its rows, its cost and its Gram fast path."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.step_contexts import random_context, split

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import objective
from dqcontrol.controllers.terms.tracking import TrackingTerm


def numpy_w(ctx: StepContext, gain: float) -> np.ndarray:
    """``w_i = dx_d/dσ + K (x_d - x̂_i)`` (docs/theory.md §4.2)."""
    return ctx.target_derivatives + gain * (ctx.targets - ctx.poses)


@pytest.mark.parametrize("p", [1, 4])
def test_tracking_rows_are_j_qd_minus_s_w(lbr4p, p):
    ctx = random_context(lbr4p, p, seed=p)
    term = TrackingTerm(gain_per_s=7.0, weight=2.5)
    res = term.residual(ctx)
    z = np.random.default_rng(0).normal(size=ctx.layout.num_vars)
    qd, s = split(ctx.layout, z)
    w = numpy_w(ctx, 7.0)
    expected = np.einsum("pkn,pn->pk", ctx.jacobians, qd) - s[:, None] * w
    np.testing.assert_allclose(res.value(ctx.layout, z), expected.ravel(), atol=1e-12)
    assert res.weight == 2.5 and res.name == "tracking"
    # the fast path: 2 λ1 G_iᵀ G_i added to each block
    hessian = np.ones((p, 8, 8))
    assert term.add_gram(ctx, hessian)
    g = np.concatenate([ctx.jacobians, -w[:, :, None]], axis=2)
    np.testing.assert_allclose(
        hessian, 1.0 + 2.0 * 2.5 * np.einsum("pki,pkj->pij", g, g), rtol=1e-13, atol=1e-13
    )
    # its cost as objective() reads it: ½ zᵀ P z + cᵀ z = λ1 ‖J qd - s w‖²
    p_mat, c = objective(ctx.layout, (res,))
    assert 0.5 * z @ p_mat @ z + c @ z == pytest.approx(2.5 * np.sum(expected**2), rel=1e-12)


def test_tracking_without_scaling_variables_asks_for_w(lbr4p):
    ctx = random_context(lbr4p, 3, seed=5, with_scaling=False)
    term = TrackingTerm(gain_per_s=4.0)
    res = term.residual(ctx)
    z = np.random.default_rng(1).normal(size=ctx.layout.num_vars)
    qd, _ = split(ctx.layout, z)
    expected = np.einsum("pkn,pn->pk", ctx.jacobians, qd) - numpy_w(ctx, 4.0)
    np.testing.assert_allclose(res.value(ctx.layout, z), expected.ravel(), atol=1e-12)
    assert not term.add_gram(ctx, np.zeros((3, 7, 7)))  # no fast path: b ≠ 0
