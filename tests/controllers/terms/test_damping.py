"""The damping term (dqcontrol/controllers/terms/damping.py): its rows are the decision's
joint velocities (and scalings when asked), and its cost summed with the scaling term's by
``objective`` is ``λ2 Σ (1 - s)² + μ Σ ‖qd‖²`` (docs/theory.md §4.2)."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.step_contexts import random_context, split

from dqcontrol.controllers.core.problem import objective
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.controllers.terms.scaling import ScalingTerm


def test_damping_rows_and_the_summed_cost(lbr4p):
    ctx = random_context(lbr4p, 5, seed=2)
    layout = ctx.layout
    z = np.random.default_rng(2).normal(size=layout.num_vars)
    qd, s = split(layout, z)
    scaling = ScalingTerm(layout, weight=1e-3).residual(ctx)
    damping = DampingTerm(layout, 1e-6).residual(ctx)
    np.testing.assert_allclose(damping.value(layout, z), qd.ravel(), atol=0)
    both = DampingTerm(layout, 1e-6, include_scaling=True).residual(ctx)
    np.testing.assert_allclose(both.value(layout, z), z, atol=0)
    assert not damping.held
    # the costs summed by objective(): λ2 Σ (1 - s)² + μ Σ ‖qd‖² (+ constant)
    p_mat, c = objective(layout, (scaling, damping))
    value = 0.5 * z @ p_mat @ z + c @ z
    expected = 1e-3 * np.sum((1.0 - s) ** 2) + 1e-6 * np.sum(qd**2) - 1e-3 * s.size
    assert value == pytest.approx(expected, rel=1e-12)
