"""The path-error term (dqcontrol/controllers/terms/path_error.py): its rows with the time
weights, and its tangent projectors, against a plain numpy formation (docs/theory.md §8.2)."""

from __future__ import annotations

import numpy as np
from controllers.terms.step_contexts import random_context
from controllers.terms.test_path_error_kernels import CONJ, PURE, numpy_path_rows

from dqcontrol.controllers.terms.path_error import PathErrorTerm, tangent_projectors
from dqcontrol.dq.algebra import hamiplus8


def test_the_term_gives_the_kernel_rows_with_the_time_weights(lbr4p):
    ctx = random_context(lbr4p, 4, seed=7)
    res = PathErrorTerm(2.0, 0.5).residual(ctx)
    pred = ctx.prediction
    a_ref, b_ref = numpy_path_rows(
        ctx.poses, ctx.targets, ctx.target_derivatives, ctx.jacobians, pred.q_base,
        pred.q_lin, pred.sigma_base, pred.sigma_lin, pred.weights, pred.phase_weights,
    )  # fmt: skip
    a = res.dense(ctx.layout)  # formed from the rows of each state
    assert res.A is None and res.states is not None
    np.testing.assert_allclose(a, a_ref, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(res.b, b_ref, rtol=1e-13, atol=1e-14)
    assert a.flags.writeable and res.row_weights.size == res.b.size


def test_the_projector_basis_gives_the_tangent_projectors():
    x = np.random.default_rng(9).normal(size=(3, 8))
    expected = np.array([hamiplus8(CONJ * xi)[PURE] for xi in x])
    np.testing.assert_allclose(tangent_projectors(x), expected, rtol=1e-15, atol=1e-15)
