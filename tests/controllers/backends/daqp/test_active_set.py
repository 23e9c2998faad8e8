"""The optimum on a guessed active set and its KKT check, against DAQP solving the same
QPs from a cold start and against scipy's SLSQP."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.optimize import minimize

from dqcontrol.controllers.backends.daqp.active_set import (
    DEPENDENT_ROWS,
    INFEASIBLE,
    SOLVED,
    WRONG_SIGN,
    dense_factor,
    solve_on_active_set,
)
from dqcontrol.controllers.backends.daqp.backend import DaqpBackend, _factor
from dqcontrol.controllers.core.problem import DenseQP
from dqcontrol.controllers.linalg.entries import nonzero_entries


def _random_qp(rng: np.random.Generator, n: int = 12, rows: int = 10) -> DenseQP:
    """A strictly convex QP whose unconstrained optimum breaks several bounds."""
    g = rng.standard_normal((n + 3, n))
    p_mat = g.T @ g + 0.1 * np.eye(n)
    c = 3.0 * rng.standard_normal(n)
    general = rng.standard_normal((rows, n))
    a = np.vstack([np.eye(n), general])
    lower = np.concatenate([-np.ones(n), -1.0 - rng.random(rows)])
    upper = np.concatenate([np.ones(n), 1.0 + rng.random(rows)])
    return DenseQP(p_mat, c, a, lower, upper)


def _cold(qp: DenseQP):
    sol = DaqpBackend(reuse_active_set=False).solve("cold", qp)
    assert sol.ok and sol.duals is not None
    return sol


def _on(qp: DenseQP, active, at_upper, changes: int = 0, sparse: bool = False):
    factor = _factor(qp.P)
    assert factor is not None
    z, duals = np.empty(qp.c.size), np.empty(qp.A.shape[0])
    general = np.ascontiguousarray(qp.A[qp.c.size :])
    entries = nonzero_entries(general) if sparse else np.zeros((0, 3))
    if sparse:  # the rows from their entries alone
        general = np.zeros((0, qp.c.size))
    status, _active, _at_upper, _changes = solve_on_active_set(
        dense_factor(factor), qp.c, general, entries, sparse, qp.lower, qp.upper, active,
        at_upper,
        1e-9, 1e-9, changes, z, duals,
    )  # fmt: skip
    return status, z, duals


@pytest.mark.parametrize("seed", range(8))
def test_the_true_active_set_gives_the_optimum_and_its_duals(seed):
    qp = _random_qp(np.random.default_rng(seed))
    ref = _cold(qp)
    active = np.flatnonzero(ref.duals)
    assert active.size > 0, "the draw must have active rows"
    status, z, duals = _on(qp, active, ref.duals[active] > 0.0)
    assert status == SOLVED
    np.testing.assert_allclose(z, ref.x, atol=1e-9)
    np.testing.assert_allclose(duals, ref.duals, atol=1e-8)
    # the optimum of scipy's SLSQP on the same problem, as an independent reference
    p_mat, c, a, lo, up = qp.P, qp.c, qp.A, qp.lower, qp.upper
    cons = [
        {"type": "ineq", "fun": lambda x: a @ x - lo},
        {"type": "ineq", "fun": lambda x: up - a @ x},
    ]
    other = minimize(
        lambda x: 0.5 * x @ p_mat @ x + c @ x, np.zeros(c.size), jac=lambda x: p_mat @ x + c,
        constraints=cons, method="SLSQP", options={"ftol": 1e-14, "maxiter": 500},
    )  # fmt: skip
    np.testing.assert_allclose(z, other.x, atol=1e-5)


@pytest.mark.parametrize("seed", range(8))
def test_a_wrong_guess_is_refused(seed):
    qp = _random_qp(np.random.default_rng(seed))
    ref = _cold(qp)
    active = np.flatnonzero(ref.duals)
    at_upper = ref.duals[active] > 0.0
    # one active row dropped: that row is then broken at the unconstrained point
    status, _z, _d = _on(qp, active[1:], at_upper[1:])
    assert status == INFEASIBLE
    # one active row held at its other bound: infeasible or of the wrong sign
    flipped = at_upper.copy()
    flipped[0] = not flipped[0]
    status, _z, _d = _on(qp, active, flipped)
    assert status in (INFEASIBLE, WRONG_SIGN)
    # an inactive row added at the bound it does not touch: its multiplier has the wrong
    # sign, or another row breaks
    idle = np.setdiff1d(np.arange(qp.A.shape[0]), active)[0]
    value = float(qp.A[idle] @ ref.x)
    toward = value > 0.5 * (qp.lower[idle] + qp.upper[idle])
    status, _z, _d = _on(qp, np.append(active, idle), np.append(at_upper, not toward))
    assert status in (INFEASIBLE, WRONG_SIGN)


@pytest.mark.parametrize("seed", range(6))
def test_the_check_over_the_non_zero_entries_is_the_dense_one(seed):
    """General rows with many zeros: summed over their non-zero entries, the check finds
    the same rows, so right and wrong guesses, mended or not, end in the same status,
    point and multipliers, bit for bit."""
    rng = np.random.default_rng(200 + seed)
    qp = _random_qp(rng)
    n = qp.c.size
    general = qp.A[n:] * (rng.random(qp.A[n:].shape) < 0.3)
    qp = DenseQP(qp.P, qp.c, np.vstack([np.eye(n), general]), qp.lower, qp.upper)
    ref = _cold(qp)
    true = np.flatnonzero(ref.duals)
    idle = np.setdiff1d(np.arange(qp.A.shape[0]), true)
    sides = ref.duals[true] > 0.0
    guesses = [
        (true, sides),
        (true[1:], sides[1:]),
        (np.append(true, idle[-1]), np.append(sides, True)),
    ]
    for (guess, at_upper), changes in itertools.product(guesses, (0, 3)):
        dense = _on(qp, guess, at_upper, changes)
        sparse = _on(qp, guess, at_upper, changes, sparse=True)
        assert dense[0] == sparse[0]
        np.testing.assert_array_equal(sparse[1], dense[1])
        np.testing.assert_array_equal(sparse[2], dense[2])


def test_repeated_active_rows_are_reported_dependent():
    qp = _random_qp(np.random.default_rng(0))
    a = np.vstack([qp.A, qp.A[:1]])  # the first bound twice
    qp2 = DenseQP(qp.P, qp.c, a, np.append(qp.lower, -1.0), np.append(qp.upper, 1.0))
    status, _z, _d = _on(qp2, np.array([0, a.shape[0] - 1]), np.array([True, True]))
    assert status == DEPENDENT_ROWS


def test_equal_bounds_take_a_multiplier_of_either_sign():
    p_mat, c = np.eye(2), np.array([-1.0, 1.0])
    a = np.eye(2)
    lo = np.array([0.5, 0.5])  # both fixed at 0.5: the first pulled up, the second down
    qp = DenseQP(p_mat, c, a, lo, lo.copy())
    status, z, duals = _on(qp, np.array([0, 1]), np.array([True, True]))
    assert status == SOLVED
    np.testing.assert_allclose(z, [0.5, 0.5])
    np.testing.assert_allclose(duals, [0.5, -1.5])


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


@pytest.mark.parametrize("seed", range(6))
def test_every_accepted_set_gives_the_optimum(seed):
    """Guesses near the true active set (a row dropped, a row added at a random bound, a
    side flipped), mended up to four times: whenever the answer is accepted it is DAQP's
    optimum."""
    rng = np.random.default_rng(100 + seed)
    qp = _random_qp(rng)
    ref = _cold(qp)
    true = np.flatnonzero(ref.duals)
    idle = np.setdiff1d(np.arange(qp.A.shape[0]), true)
    accepted = 0
    for _ in range(30):
        keep = rng.random(true.size) < 0.8
        guess = np.concatenate([true[keep], rng.choice(idle, size=int(rng.integers(0, 2)))])
        added = np.ones(guess.size - int(keep.sum()), dtype=bool)
        at_upper = np.concatenate([ref.duals[true[keep]] > 0.0, added])
        at_upper ^= rng.random(guess.size) < 0.1
        status, z, duals = _on(qp, guess, at_upper, changes=4)
        if status == SOLVED:
            accepted += 1
            np.testing.assert_allclose(z, ref.x, atol=1e-9)
            np.testing.assert_allclose(duals, ref.duals, atol=1e-8)
    assert accepted >= 5, "guesses near the optimum's set must be mended to it"


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
