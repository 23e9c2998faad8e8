"""The scaling range (dqcontrol/controllers/limits/scaling_range.py): free ``[s_min, s_max]``
bounds, or fixed ones without scaling (docs/theory.md §3), as the built problem reads them."""

from __future__ import annotations

import numpy as np
from controllers.terms.step_contexts import random_context

from dqcontrol.controllers.core.levels import build_problem
from dqcontrol.controllers.core.problem import Level
from dqcontrol.controllers.limits.scaling_range import ScalingRange
from dqcontrol.controllers.terms.damping import DampingTerm


def test_scaling_range_fixed_without_scaling(lbr4p):
    ctx = random_context(lbr4p, 2, seed=1)
    free = ScalingRange(ctx.layout, 0.0, 1.0).rows(ctx)
    fixed = ScalingRange(ctx.layout, 1.0, 1.0).rows(ctx)
    assert not free.fixed and fixed.fixed
    np.testing.assert_array_equal(fixed.index, ctx.layout.s_index())
    problem = build_problem(ctx, (Level((DampingTerm(ctx.layout, 1.0),)),),
                            (ScalingRange(ctx.layout, 1.0, 1.0),))  # fmt: skip
    np.testing.assert_array_equal(np.flatnonzero(problem.fixed), ctx.layout.s_index())


def test_the_bounds_of_every_block(lbr4p):
    ctx = random_context(lbr4p, 4, seed=2)
    rows = ScalingRange(ctx.layout, 0.1, 1.2).rows(ctx)
    np.testing.assert_array_equal(rows.index, ctx.layout.s_index())
    np.testing.assert_array_equal(rows.lower, np.full(4, 0.1))
    np.testing.assert_array_equal(rows.upper, np.full(4, 1.2))
    assert not rows.hard and ScalingRange(ctx.layout).rows(ctx).lower.tolist() == [0.0] * 4
