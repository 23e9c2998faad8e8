"""The applied command's own box (dqcontrol/controllers/limits/applied_box.py): velocity ∩
position through one period ∩ braking on ``qd_0``, against the numpy joint box
(docs/theory.md §5) at states near and beyond the limits."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.limits.test_joint_box import near_limits, numpy_box
from controllers.terms.step_contexts import random_context

from dqcontrol.controllers.limits.applied_box import AppliedCommandBox


@pytest.mark.parametrize("seed", range(4))
def test_the_bounds_of_qd0_are_the_numpy_box(lbr4p, seed):
    ctx = random_context(lbr4p, 3, seed=seed)
    near_limits(ctx, seed)
    lim = lbr4p.limits
    q_min, q_max = lim.q_min + 5e-3, lim.q_max - 5e-3
    qd_max = np.linspace(1.0, 3.0, lbr4p.nq)
    limit = AppliedCommandBox(ctx.layout, q_min, q_max, qd_max, ctx.period_s)
    rows = limit.rows(ctx)
    lo, hi = numpy_box(ctx.q, q_min, q_max, qd_max, ctx.period_s, ctx.a_max[0])
    assert rows.name == "applied_box" and not rows.hard
    np.testing.assert_array_equal(rows.index, ctx.layout.qd_index()[0])
    np.testing.assert_allclose(rows.lower, lo, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(rows.upper, hi, rtol=1e-14, atol=1e-14)
    # a new a_max is read, not the one cached from the step before
    ctx.a_max = ctx.a_max * 0.5
    lo, hi = numpy_box(ctx.q, q_min, q_max, qd_max, ctx.period_s, ctx.a_max[0])
    np.testing.assert_allclose(limit.rows(ctx).upper, hi, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(limit.rows(ctx).lower, lo, rtol=1e-14, atol=1e-14)
