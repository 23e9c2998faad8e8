"""The braking term (dqcontrol/controllers/terms/braking.py): the progress rows with the
reference 0, ``sqrt(c_i) (0 - s_i)`` (docs/theory.md §8.10), against the weights written
out."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.terms.braking import BrakingTerm
from dqcontrol.controllers.terms.progress import ProgressTerm


def test_the_rows_pull_every_scaling_to_zero_earliest_most():
    layout = DecisionLayout(2, np.array([0.0, 0.1, 0.3]), np.array([0.1, 0.2, 0.2]))
    term = BrakingTerm(layout, weight=3.0)
    res = term.residual(None)
    assert res.name == "braking" and res.weight == 3.0
    np.testing.assert_array_equal(res.b, np.zeros(3))
    z = np.random.default_rng(3).normal(size=layout.num_vars)
    s = z.reshape(3, 3)[:, 2]
    scale = np.sqrt(layout.durations_s * np.arange(3, 0, -1) / 0.5)
    np.testing.assert_allclose(res.value(layout, z), -scale * s, rtol=1e-15, atol=0)
    # the same rows as the progress term's; only the reference differs
    progress = ProgressTerm(layout).residual(type("C", (), {"lag_s": 0.0})())
    np.testing.assert_array_equal(res.blocks, progress.blocks)
    assert term.residual(None).b is res.b  # the constant b, built once
