"""The compiled Cholesky factorisation (:mod:`dqcontrol.controllers.linalg.cholesky`) against
numpy's, and its refusal of matrices that are not safely positive definite."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.linalg.cholesky import cholesky_above, cholesky_into


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    g = rng.standard_normal((n + 2, n))
    return g.T @ g + 1e-3 * np.eye(n)


@pytest.mark.parametrize("n", [1, 2, 7, 16, 33])
def test_the_factor_is_numpys(n):
    rng = np.random.default_rng(n)
    a = _spd(rng, n)
    out = np.full((n, n), np.nan)
    assert cholesky_into(a, out, 1e-12)
    np.testing.assert_allclose(np.tril(out), np.linalg.cholesky(a), rtol=1e-10, atol=1e-12)
    # a shift factorises a - shift I
    shift = 0.5 * np.linalg.eigvalsh(a)[0]
    assert cholesky_into(a, out, 1e-12, shift)
    want = np.linalg.cholesky(a - shift * np.eye(n))
    np.testing.assert_allclose(np.tril(out), want, rtol=1e-9, atol=1e-12)


def test_only_the_lower_triangle_is_read_and_in_place_works():
    rng = np.random.default_rng(3)
    a = _spd(rng, 6)
    want = np.linalg.cholesky(a)
    garbage = a.copy()
    garbage[np.triu_indices(6, 1)] = 1e6  # the upper triangle is never read
    out = np.zeros((6, 6))
    assert cholesky_into(garbage, out, 1e-12)
    np.testing.assert_allclose(np.tril(out), want, rtol=1e-12)
    assert cholesky_into(garbage, garbage, 1e-12)  # out may be a itself
    np.testing.assert_allclose(np.tril(garbage), want, rtol=1e-12)


def test_a_matrix_that_is_not_safely_definite_is_refused():
    rng = np.random.default_rng(4)
    g = rng.standard_normal((3, 6))
    out = np.zeros((6, 6))
    assert not cholesky_into(g.T @ g, out, 1e-12)  # rank 3
    assert not cholesky_into(-_spd(rng, 4), np.zeros((4, 4)), 1e-12)
    nan = _spd(rng, 4)
    nan[2, 2] = np.nan
    assert not cholesky_into(nan, np.zeros((4, 4)), 1e-12)
    # a pivot below the share of the largest diagonal entry
    assert not cholesky_into(np.diag([1.0, 1e-13]), np.zeros((2, 2)), 1e-12)
    assert cholesky_into(np.diag([1.0, 1e-11]), np.zeros((2, 2)), 1e-12)


def test_cholesky_above_takes_an_absolute_threshold():
    a = np.diag([4.0, 0.25])
    out = np.zeros((2, 2))
    assert cholesky_above(a, out, 0.2, 0.0)
    np.testing.assert_array_equal(out, np.diag([2.0, 0.5]))
    assert not cholesky_above(a, out, 0.25, 0.0)  # a pivot must be above, not equal
    assert not cholesky_above(a, out, 0.0, 0.3)  # shifted below zero
