"""The DAQP block path (:mod:`dqcontrol.controllers.backends.daqp.blocks`): no stale
equality (a row with lower == upper at the first solve after a setup must move freely once
its bounds widen again), ``solve_dense`` (the whole Hessian) against ``solve``, the
least-distance form against the plain one, and the predictive controllers' solves taking that
form."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from dqcontrol.controllers.backends.daqp.blocks import DaqpBlocks
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories import Circle


def _qp(**kwargs) -> DaqpBlocks:
    pattern = sp.csc_matrix(np.triu(np.ones((2, 2))))
    return DaqpBlocks(pattern, sp.identity(2, format="csc"), **kwargs)


def _values(h: np.ndarray) -> np.ndarray:
    """The upper triangle of ``h`` in CSC order (the controllers' p_values)."""
    return np.array([h[0, 0], h[0, 1], h[1, 1]])


H = np.eye(2)
C = np.array([-0.5, 0.0])  # unconstrained optimum x = (0.5, 0)


def test_a_collapsed_box_at_setup_is_not_kept_as_an_equality():
    qp = _qp()
    first = qp.solve(_values(H), C, np.array([0.2, -1.0]), np.array([0.2, 1.0]))
    assert first.ok
    np.testing.assert_allclose(first.x, [0.2, 0.0], atol=1e-12)
    wide = qp.solve(_values(H), C, np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    assert wide.ok
    np.testing.assert_allclose(wide.x, [0.5, 0.0], atol=1e-12)  # was 0.2 or 1.0: pinned


def test_equalities_by_design_stay_fixed():
    qp = _qp(equality_rows=np.array([1]))
    lo, up = np.array([-1.0, 0.3]), np.array([1.0, 0.3])
    for _ in range(3):
        sol = qp.solve(_values(H), C, lo, up)
        assert sol.ok
        np.testing.assert_allclose(sol.x, [0.5, 0.3], atol=1e-12)


def test_solve_dense_equals_solve():
    """``solve_dense`` (whole H, checked bounds) and ``solve`` (stored values, checks) give
    the same solutions, through setups, updates, a new f and failures."""
    m = 4
    pattern = sp.csc_matrix(np.triu(np.ones((m, m))))
    a_matrix = sp.identity(m, format="csc")
    fast, ref = DaqpBlocks(pattern, a_matrix), DaqpBlocks(pattern, a_matrix)
    rows, cols = np.triu_indices(m)
    order = np.lexsort((rows, cols))  # CSC order of the upper triangle
    rng = np.random.default_rng(5)
    c = np.array([0.1, -0.2, 0.0, -2e-3])
    for k in range(300):
        g = rng.normal(size=(6, m))
        h = g.T.dot(g) + 1e-6 * np.eye(m)
        lower = rng.uniform(-1.0, 0.0, m)
        upper = lower + rng.uniform(0.0, 1.0, m)
        if k % 50 == 10:
            upper[1] = lower[1]  # a collapsed box
        if k % 100 == 60:
            c = c + 0.01  # a new f
        if k % 70 == 30:
            h = -h  # not convex: both fail and rebuild
        x_fast, ok, status, iterations, t = fast.solve_dense(h.copy(), c, lower, upper)
        sol = ref.solve(h[rows[order], cols[order]], c, lower, upper)
        assert (ok, status, iterations) == (sol.ok, sol.status, sol.iterations)
        assert t >= 0.0
        if ok:
            np.testing.assert_array_equal(x_fast, sol.x)
        else:
            assert x_fast is None and sol.x is None


# ------------------------------------------------------------------ block-diagonal P


def _block_problem(rng, blocks: int, size: int, equality: bool):
    """A predictive-like QP: block-diagonal P (one block per instant), box bounds on every
    variable and coupling rows ``|z_(b+1),j - z_b,j| ≤ d`` between consecutive blocks."""
    n = blocks * size
    h = np.zeros((n, n))
    for b in range(blocks):
        g = rng.standard_normal((size + 2, size))
        h[b * size : (b + 1) * size, b * size : (b + 1) * size] = g.T @ g + 1e-6 * np.eye(size)
    rows = []
    for b in range(blocks - 1):
        for j in range(size - 1):
            row = np.zeros(n)
            row[b * size + j], row[(b + 1) * size + j] = -1.0, 1.0
            rows.append(row)
    a = sp.vstack([sp.identity(n, format="csc"), sp.csc_matrix(np.array(rows))], format="csc")
    pattern = sp.csc_matrix(np.triu(h != 0))
    pattern.sort_indices()
    pat = pattern.tocoo()
    lower = np.concatenate((rng.uniform(-2.0, -0.1, n), np.full(len(rows), -0.3)))
    upper = np.concatenate((rng.uniform(0.1, 2.0, n), np.full(len(rows), 0.3)))
    lower[rng.integers(0, n)] = -np.inf  # unbounded sides are clamped, not refused
    upper[n + rng.integers(0, len(rows))] = np.inf
    eq = np.arange(blocks) * size + size - 1 if equality else None
    if equality:
        lower[eq] = upper[eq] = 0.25
    return h, pattern, pat, a, lower, upper, eq


def test_block_diagonal_p_as_least_distance_problem_gives_the_same_optimum():
    """``DaqpBlocks(block_size=…)`` (the least-distance form of ``qp_ldp.py``) against DAQP on
    the problem as it is, over a sequence of solves (warm active sets), with equalities by
    design, unbounded sides, an infeasible step and a block that is not positive definite
    (which falls back to the plain form and stays correct)."""
    rng = np.random.default_rng(2024)
    for blocks, size, equality in ((10, 8, False), (6, 8, True), (3, 4, False)):
        h, pattern, pat, a, lower, upper, eq = _block_problem(rng, blocks, size, equality)
        plain = DaqpBlocks(pattern, a, equality_rows=eq)
        ldp = DaqpBlocks(pattern, a, equality_rows=eq, block_size=size)
        for _ in range(12):
            hs = h * rng.uniform(0.5, 2.0)  # a new P each step, same pattern
            c = rng.standard_normal(h.shape[0])
            values = hs[pat.row, pat.col]
            ref, got = plain.solve(values, c, lower, upper), ldp.solve(values, c, lower, upper)
            assert ref.ok and got.ok and got.status == ref.status == "solved"
            scale = max(1.0, np.abs(ref.x).max())
            np.testing.assert_allclose(got.x, ref.x, rtol=0, atol=1e-9 * scale)
            if eq is not None:
                np.testing.assert_allclose(got.x[eq], 0.25, atol=1e-12)
        # contradictory coupling rows: both report infeasibility
        bad_lo, bad_up = lower.copy(), upper.copy()
        n = h.shape[0]
        bad_lo[n], bad_up[n] = 1.0, 1.0  # z_1,0 - z_0,0 = 1 …
        bad_up[0] = bad_up[size] = 0.1  # … with both in [lo, 0.1]
        bad_lo[0] = bad_lo[size] = 0.0
        ref = plain.solve(h[pat.row, pat.col], c, bad_lo, bad_up)
        got = ldp.solve(h[pat.row, pat.col], c, bad_lo, bad_up)
        assert not ref.ok and not got.ok and got.status == ref.status
        # the next feasible step is solved again (the workspace was rebuilt)
        again = ldp.solve(h[pat.row, pat.col], c, lower, upper)
        assert again.ok
    # a block with a zero pivot: the least-distance form is declined, the plain one used
    h, pattern, pat, a, lower, upper, _ = _block_problem(rng, 4, 4, False)
    h_psd = h.copy()
    h_psd[4:8, 4:8] = 0.0
    h_psd[4, 4] = h_psd[5, 5] = h_psd[6, 6] = h_psd[7, 7] = 1.0
    h_psd[5, 5] = 0.0
    ldp = DaqpBlocks(pattern, a, block_size=4)
    plain = DaqpBlocks(pattern, a)
    c = rng.standard_normal(16)
    got = ldp.solve(h_psd[pat.row, pat.col], c, lower, upper)
    ref = plain.solve(h_psd[pat.row, pat.col], c, lower, upper)
    assert got.status == ref.status
    if ref.ok:
        np.testing.assert_allclose(got.x, ref.x, atol=1e-9)


def test_block_size_must_match_the_pattern():
    pattern = sp.csc_matrix(np.triu(np.ones((4, 4))))
    with pytest.raises(ParameterError, match="not block diagonal"):
        DaqpBlocks(pattern, sp.identity(4, format="csc"), block_size=2)


def test_predictive_daqp_takes_the_least_distance_form(lbr4p):
    """The predictive controllers' DAQP solves take the least-distance form (their blocks are
    positive definite with the default μ and λ2): the plain workspace is never set up."""
    from dqcontrol.controllers import PredictiveController, PredictiveNoScalingController
    from dqcontrol.model import LBR4P_Q0

    robot = lbr4p
    for cls in (PredictiveController, PredictiveNoScalingController):
        ctrl = cls(robot, Circle(2.0), 1e-3, num_instants=6, acceleration_limit=10.0)
        q = np.array(LBR4P_Q0)
        ctrl.reset(q)
        for _ in range(200):
            res = ctrl.step(q)
            assert res.diagnostics.status == "solved"
            q = q + 1e-3 * res.qd_command
        assert ctrl.backend._blocks._block == robot.nq + 1
        assert ctrl.backend._blocks._ldp_model is not None and ctrl.backend._blocks._model is None
