"""The compiled element-wise parts of the consistent prediction
(dqcontrol/controllers/prediction/consistent_kernels.py) against the numpy expressions they
stand for (seeded random draws)."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.prediction.consistent_kernels import clip_into, states_into


def test_clip_into_is_numpys_clip():
    values = np.random.default_rng(0).normal(size=50) * 2.0
    values[[3, 7]] = [np.nan, -0.0]
    expected = np.minimum(np.maximum(values, 0.0), 1.3)
    clip_into(values, 0.0, 1.3)
    np.testing.assert_array_equal(values, expected)


@pytest.mark.parametrize("lagging", [False, True])
def test_states_into_adds_the_zero_decisions_states(lagging):
    rng = np.random.default_rng(1)
    p, n = 6, 7
    q, v0, qd, sigma = rng.normal(size=n), rng.uniform(size=p), rng.normal(size=n), 0.7
    moved, advanced = rng.normal(size=(p, n)), rng.normal(size=p)
    base = q + v0[:, None] * qd if lagging else np.repeat(q[None, :], p, axis=0)
    expected = (base + moved, sigma + advanced)
    q_base, sigma_base = np.empty((p, n)), np.empty(p)
    states_into(q, v0, qd, lagging, sigma, moved, advanced, q_base, sigma_base)
    assert np.array_equal(q_base, base) and np.array_equal(sigma_base, np.full(p, sigma))
    assert np.array_equal(moved, expected[0]) and np.array_equal(advanced, expected[1])
