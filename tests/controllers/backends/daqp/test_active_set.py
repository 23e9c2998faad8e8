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
