"""The compiled Householder QR factorisations (:mod:`dqcontrol.controllers.linalg.householder`)
against LAPACK's (numpy's and scipy's QR): ``Q R`` gives the columns back, ``Q`` is
orthogonal, and its trailing columns span the null space of the columns' transpose."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from dqcontrol.controllers.linalg.householder import applied_q, pivoted_qr, profile_qr


def _check_factorisation(a, columns, tau, pivots, reach):
    n, r = a.shape
    k = min(n, r)
    q = applied_q(columns, reach, tau, 0)
    r_mat = np.triu(columns[:k])
    np.testing.assert_allclose(q.T @ q, np.eye(n), atol=1e-12)
    np.testing.assert_array_equal(np.diag(r_mat), pivots)
    np.testing.assert_allclose(q[:, :k] @ r_mat, a, atol=1e-12 * np.abs(a).max())
    return q


@pytest.mark.parametrize(("n", "r"), [(8, 3), (12, 12), (20, 7), (5, 1)])
def test_profile_qr_with_full_reach_is_lapacks(n, r):
    rng = np.random.default_rng(n * r)
    a = rng.standard_normal((n, r))
    columns, reach = a.copy(), np.full(r, n - 1, dtype=np.int64)
    tau, pivots = profile_qr(columns, reach)
    q = _check_factorisation(a, columns, tau, pivots, reach)
    q_ref, r_ref = np.linalg.qr(a, mode="complete")
    np.testing.assert_allclose(pivots, np.diag(r_ref), rtol=1e-10)  # LAPACK's signs
    np.testing.assert_allclose(q, q_ref, atol=1e-10)
    # from `first` on: the trailing columns only, orthogonal to every column of a
    tail = applied_q(columns, reach, tau, r)
    np.testing.assert_allclose(tail, q[:, r:], atol=1e-14)
    np.testing.assert_allclose(a.T @ tail, 0.0, atol=1e-12)


def test_profile_qr_of_a_staircase_reaches_only_its_rows():
    """Columns that reach rows in steps (zero below ``reach[j]``): the short reflectors give
    the factorisation of the whole matrix."""
    rng = np.random.default_rng(7)
    n, r = 14, 6
    reach = np.array([3, 5, 7, 9, 11, 13], dtype=np.int64)
    a = rng.standard_normal((n, r))
    a[np.arange(n)[:, None] > reach[None, :]] = 0.0
    columns = a.copy()
    tau, pivots = profile_qr(columns, reach)
    _check_factorisation(a, columns, tau, pivots, reach)
    np.testing.assert_allclose(pivots, np.diag(np.linalg.qr(a)[1]), rtol=1e-10)


@pytest.mark.parametrize(("n", "r", "rank"), [(10, 6, 6), (10, 6, 3), (6, 10, 4), (9, 9, 0)])
def test_pivoted_qr_orders_by_norm_and_shows_the_rank(n, r, rank):
    rng = np.random.default_rng(100 + rank)
    a = rng.standard_normal((n, rank)) @ rng.standard_normal((rank, r))
    columns = a.copy()
    tau, pivots = pivoted_qr(columns)
    k = min(n, r)
    assert tau.shape == pivots.shape == (k,)
    magnitude = np.abs(pivots)
    assert np.all(np.diff(magnitude) <= 1e-12 * max(1.0, magnitude.max()))  # non-increasing
    _, r_ref, _ = scipy.linalg.qr(a, pivoting=True)
    np.testing.assert_allclose(magnitude, np.abs(np.diag(r_ref)), atol=1e-10)
    scale = max(1.0, magnitude.max())
    assert np.all(magnitude[:rank] > 1e-8 * scale) and np.all(magnitude[rank:] < 1e-10 * scale)
    reach = np.full(k, n - 1, dtype=np.int64)
    q = applied_q(columns, reach, tau, 0)
    np.testing.assert_allclose(q.T @ q, np.eye(n), atol=1e-12)
    # the columns after the rank span the null space of aᵀ
    np.testing.assert_allclose(a.T @ q[:, rank:], 0.0, atol=1e-10 * scale)
