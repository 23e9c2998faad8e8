"""The least-distance form of a QP (:mod:`dqcontrol.controllers.backends.daqp.least_distance`)
against numpy's formation ``M = A L⁻ᵀ``, ``w = H⁻¹ c`` and the shifted bounds, and the
optimum mapped back from the least-distance problem against quadprog's."""

from __future__ import annotations

import numpy as np
import pytest
import quadprog
import scipy.linalg
import scipy.sparse as sp

from dqcontrol.controllers.backends.daqp.least_distance import block_ldp, dense_ldp, ldp_solution


def _draw(rng: np.random.Generator, p: int, m: int, rows: int):
    g = rng.standard_normal((p, m + 2, m))
    blocks = np.einsum("pki,pkj->pij", g, g) + 0.1 * np.eye(m)
    h = scipy.linalg.block_diag(*blocks)
    n = p * m
    general = rng.standard_normal((rows, n))
    general[rng.random(general.shape) < 0.5] = 0.0
    c = 2.0 * rng.standard_normal(n)
    lower = np.concatenate([-np.ones(n), -1.0 - rng.random(rows)])
    upper = np.concatenate([np.ones(n), 1.0 + rng.random(rows)])
    lower[1], upper[-1] = -np.inf, np.inf  # open sides stay open (clamped)
    return h, general, c, lower, upper


def _numpy_ldp(h, general, c, lower, upper):
    factor = np.linalg.cholesky(h)
    linv_t = np.linalg.inv(factor).T
    a = np.vstack([np.eye(h.shape[0]), general])
    w = np.linalg.solve(h, c)
    shift = a @ w
    lo = np.maximum(lower + shift, -1e30)
    up = np.minimum(upper + shift, 1e30)
    return a @ linv_t, lo, up, linv_t, w


def _outputs(n: int, rows: int, blocks: int, block: int):
    return (np.full((n + rows, n), np.nan), np.empty(n + rows), np.empty(n + rows),
            np.empty((blocks, block, block)), np.empty(n))  # fmt: skip


@pytest.mark.parametrize(("p", "m", "rows"), [(1, 5, 0), (3, 4, 3), (6, 8, 5)])
def test_block_ldp_is_numpys_formation(p, m, rows):
    rng = np.random.default_rng(p * m + rows)
    h, general, c, lower, upper = _draw(rng, p, m, rows)
    n = p * m
    csr = sp.csr_matrix(general)
    m_out, lo, up, linv_t, w = _outputs(n, rows, p, m)
    assert block_ldp(h, m, c, lower, upper, csr.indptr.astype(np.int64),
                     csr.indices.astype(np.int64), csr.data, m_out, lo, up, linv_t, w)  # fmt: skip
    m_ref, lo_ref, up_ref, lt_ref, w_ref = _numpy_ldp(h, general, c, lower, upper)
    np.testing.assert_allclose(m_out, m_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(w, w_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(lo, lo_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(up, up_ref, rtol=1e-10, atol=1e-12)
    assert lo[1] == -1e30 and up[-1] == 1e30
    np.testing.assert_allclose(scipy.linalg.block_diag(*linv_t), lt_ref, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("rows", [0, 4])
def test_dense_ldp_is_numpys_formation(rows):
    rng = np.random.default_rng(40 + rows)
    h, general, c, lower, upper = _draw(rng, 1, 9, rows)
    m_out, lo, up, linv_t, w = _outputs(9, rows, 1, 9)
    assert dense_ldp(np.linalg.cholesky(h), c, lower, upper, general, m_out, lo, up, linv_t, w)
    m_ref, lo_ref, up_ref, lt_ref, w_ref = _numpy_ldp(h, general, c, lower, upper)
    np.testing.assert_allclose(m_out, m_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(w, w_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(lo, lo_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(up, up_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(linv_t[0], lt_ref, rtol=1e-10, atol=1e-12)
    singular = np.linalg.cholesky(h)
    singular[3, 3] = 0.0  # no inverse
    assert not dense_ldp(singular, c, lower, upper, general, m_out, lo, up, linv_t, w)


def test_the_least_distance_optimum_maps_back_to_the_qps():
    """``minimize ½‖u‖²`` under ``lo ≤ M u ≤ up``, solved by quadprog, gives through
    ``z = L⁻ᵀ u - w`` the optimum of the QP itself."""
    rng = np.random.default_rng(5)
    p, m, rows = 3, 4, 3
    h, general, c, lower, upper = _draw(rng, p, m, rows)
    lower[1] = -1.0  # every side finite for quadprog
    upper[-1] = 2.0
    n = p * m
    csr = sp.csr_matrix(general)
    m_out, lo, up, linv_t, w = _outputs(n, rows, p, m)
    assert block_ldp(h, m, c, lower, upper, csr.indptr.astype(np.int64),
                     csr.indices.astype(np.int64), csr.data, m_out, lo, up, linv_t, w)  # fmt: skip
    u = quadprog.solve_qp(np.eye(n), np.zeros(n), np.vstack([m_out, -m_out]).T,
                          np.concatenate([lo, -up]))[0]  # fmt: skip
    a = np.vstack([np.eye(n), general])
    z_ref = quadprog.solve_qp(h, -c, np.vstack([a, -a]).T, np.concatenate([lower, -upper]))[0]
    np.testing.assert_allclose(ldp_solution(linv_t, u, w), z_ref, atol=1e-9)


def test_a_block_that_is_not_safely_definite_is_refused():
    rng = np.random.default_rng(6)
    h, general, c, lower, upper = _draw(rng, 2, 3, 0)
    h[3:, 3:] = np.outer([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])  # rank 1
    m_out, lo, up, linv_t, w = _outputs(6, 0, 2, 3)
    empty = np.zeros(1, dtype=np.int64)
    assert not block_ldp(h, 3, c, lower, upper, empty, empty[:0], np.zeros(0), m_out, lo, up,
                         linv_t, w)  # fmt: skip
