"""``lane_dot`` (:mod:`dqcontrol.controllers.linalg.lanes`): numpy's ``einsum`` of a
contiguous axis bit for bit, the dot product to rounding, every product summed once (against
``math.fsum``) in its order of two lanes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol.controllers.linalg.lanes import lane_dot


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 8, 9, 15, 16, 17, 31, 64, 101])
def test_lane_dot_is_einsums_sum(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        x, y = rng.standard_normal(n) * 1e3, rng.standard_normal(n)
        assert lane_dot(x, y) == np.einsum("k,k->", x, y)
        np.testing.assert_allclose(lane_dot(x, y), x @ y, rtol=1e-12, atol=1e-9)


def test_the_order_is_two_lanes_not_the_running_sum():
    """Numbers chosen so that the order shows: the left-to-right sum gives 1, the two lanes
    (``1e16 - 1e16`` and ``1 + 1``) give 2."""
    x, y = np.array([1e16, 1.0, -1e16, 1.0]), np.ones(4)
    assert ((1e16 + 1.0) - 1e16) + 1.0 == 1.0
    assert lane_dot(x, y) == 2.0


@pytest.mark.parametrize("length", [0, 1, 2, 5, 7, 8, 9, 15, 16, 21])
def test_lane_dot_sums_every_product_once(length):
    rng = np.random.default_rng(length)
    x, y = rng.normal(size=length), rng.normal(size=length)
    exact = math.fsum(x * y)
    bound = 1e-15 * length * float(np.sum(np.abs(x * y)))
    assert abs(lane_dot(x, y) - exact) <= bound
    # the order: two running sums over even and odd entries, blocks of eight last pair first
    if length == 8:
        even = x[6] * y[6] + x[4] * y[4] + x[2] * y[2] + x[0] * y[0]
        odd = x[7] * y[7] + x[5] * y[5] + x[3] * y[3] + x[1] * y[1]
        assert lane_dot(x, y) == even + odd
