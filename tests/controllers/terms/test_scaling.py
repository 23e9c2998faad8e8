"""The scaling term (dqcontrol/controllers/terms/scaling.py): its rows ``s_i - 1`` against
the decision's scalings (docs/theory.md §4.2), held constant."""

from __future__ import annotations

import numpy as np
from controllers.terms.step_contexts import random_context, split

from dqcontrol.controllers.terms.scaling import ScalingTerm


def test_scaling_rows_are_s_minus_one(lbr4p):
    ctx = random_context(lbr4p, 5, seed=2)
    layout = ctx.layout
    z = np.random.default_rng(2).normal(size=layout.num_vars)
    _, s = split(layout, z)
    scaling = ScalingTerm(layout, weight=1e-3).residual(ctx)
    np.testing.assert_allclose(scaling.value(layout, z), s - 1.0, atol=0)
    assert scaling.held
