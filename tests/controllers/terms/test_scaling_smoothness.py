"""The scaling smoothness term (dqcontrol/controllers/terms/scaling_smoothness.py): its rows
``s_0 - s_applied`` and ``s_i - s_(i-1)`` (docs/theory.md §8.3) against numpy's ``diff``."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.terms.scaling_smoothness import ScalingSmoothnessTerm


@pytest.mark.parametrize("s_prev", [0.0, 0.37])
def test_the_rows_are_differences_of_the_scalings(s_prev):
    layout = DecisionLayout(3, np.array([0.0, 0.1, 0.3, 0.6]), np.array([0.1, 0.2, 0.3, 0.3]))
    term = ScalingSmoothnessTerm(layout)
    assert term.weight == 1e-2
    res = term.residual(SimpleNamespace(s_prev=s_prev))
    z = np.random.default_rng(5).normal(size=layout.num_vars)
    s = z[layout.s_index()]
    expected = np.diff(np.r_[s_prev, s])
    np.testing.assert_allclose(res.value(layout, z), expected, rtol=1e-15, atol=1e-15)
    assert res.weight == 1e-2 and res.b.shape == (4,)
