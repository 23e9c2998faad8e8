"""The DAQP backend (:mod:`dqcontrol.controllers.backends.daqp.backend`): its reuse of the
last active set against DAQP from a cold start, its fallback when the set changes, and its
Cholesky factor against numpy's."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.backends.daqp.test_active_set import _cold, _random_qp

from dqcontrol.controllers.backends.daqp.backend import DaqpBackend, _factor
from dqcontrol.controllers.core.problem import DenseQP


def test_the_backend_reuses_the_active_set_along_a_drifting_sequence():
    """Small changes of the data keep the active set: the backend answers without DAQP
    (0 iterations), and every answer equals DAQP's own."""
    rng = np.random.default_rng(4)
    base = _random_qp(rng)
    reuse, plain = DaqpBackend(), DaqpBackend(reuse_active_set=False)
    reused = 0
    for k in range(40):
        drift = 1e-3 * k
        qp = DenseQP(base.P, base.c + drift, base.A, base.lower - drift, base.upper)
        a, b = reuse.solve(0, qp), plain.solve(0, qp)
        assert a.ok and b.ok
        np.testing.assert_allclose(a.x, b.x, atol=1e-9)
        reused += a.iterations == 0
    assert reused >= 30


def test_the_backend_falls_back_to_daqp_when_the_set_changes():
    rng = np.random.default_rng(5)
    qp = _random_qp(rng)
    backend = DaqpBackend()
    first = backend.solve(0, qp)
    # a new linear term moves the optimum to another vertex
    moved = DenseQP(qp.P, -qp.c, qp.A, qp.lower, qp.upper)
    second = backend.solve(0, moved)
    assert second.ok and second.iterations > 0
    np.testing.assert_allclose(second.x, _cold(moved).x, atol=1e-9)
    assert not np.allclose(first.x, second.x)


@pytest.mark.parametrize("n", [3, 20, 40, 41, 80])
def test_the_factor_is_cholesky_and_refuses_a_singular_matrix(n):
    """The compiled factorisation (small ``P``) and LAPACK's (large) give numpy's factor,
    and neither accepts a matrix that is not safely positive definite."""
    rng = np.random.default_rng(n)
    g = rng.standard_normal((n + 2, n))
    p_mat = g.T @ g + 1e-3 * np.eye(n)
    np.testing.assert_allclose(_factor(p_mat), np.linalg.cholesky(p_mat), atol=1e-10)
    low_rank = g.T[:, : n // 2] @ g.T[:, : n // 2].T  # rank n/2
    assert _factor(low_rank) is None
    assert _factor(-p_mat) is None


def test_a_changed_row_count_keeps_the_rows_that_exist_as_the_guess():
    """A limit that adds or drops rows between steps: the last set's rows that still exist
    are the guess, and whatever the backend answers is DAQP's optimum; a row added far
    from its bounds leaves the set as it was, without DAQP."""
    rng = np.random.default_rng(6)
    qp = _random_qp(rng)
    backend = DaqpBackend()
    assert backend.solve(0, qp).ok
    calls = []
    for name in ("_solve_ldp", "_solve_as_is"):
        inner = getattr(backend, name)
        setattr(backend, name, lambda *a, _f=inner: calls.append(1) or _f(*a))
    spare = rng.standard_normal(qp.c.size)
    grown = DenseQP(
        qp.P, qp.c, np.vstack([qp.A, spare]), np.append(qp.lower, -50.0), np.append(qp.upper, 50.0)
    )
    sol = backend.solve(0, grown)
    assert sol.ok and not calls
    np.testing.assert_allclose(sol.x, _cold(grown).x, atol=1e-9)
    shrunk = DenseQP(qp.P, qp.c, qp.A[:-3], qp.lower[:-3], qp.upper[:-3])
    sol = backend.solve(0, shrunk)
    assert sol.ok
    np.testing.assert_allclose(sol.x, _cold(shrunk).x, atol=1e-9)
