"""The compiled joint-wise distance (dqcontrol/controllers/prediction/distance.py) against
``np.max(np.abs(a - b))``: seeded random vectors, NaN and empty inputs."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.prediction.distance import max_abs_difference


@pytest.mark.parametrize("n", [1, 7, 50])
def test_max_abs_difference_is_numpys(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        a, b = rng.normal(size=n), rng.normal(size=n)
        assert max_abs_difference(a, b) == np.max(np.abs(a - b))
    a = rng.normal(size=n)
    assert max_abs_difference(a, a.copy()) == 0.0
    assert max_abs_difference(np.zeros(n), -np.zeros(n)) == 0.0  # -0.0 and 0.0 alike


def test_a_nan_difference_gives_nan_and_empty_arrays_minus_infinity():
    a, b = np.array([1.0, 5.0, np.nan, 9.0]), np.zeros(4)
    assert np.isnan(max_abs_difference(a, b)) and np.isnan(np.max(np.abs(a - b)))
    assert np.isnan(max_abs_difference(np.array([np.inf]), np.array([np.inf])))
    assert max_abs_difference(np.zeros(0), np.zeros(0)) == -np.inf
