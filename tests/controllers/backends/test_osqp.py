"""The OSQP backend (:mod:`dqcontrol.controllers.backends.osqp`) against quadprog on seeded
random QPs (dense and block diagonal), its refinement to the exact optimum, and its checks
of settings and bounds."""

from __future__ import annotations

import numpy as np
import pytest
import quadprog
import scipy.linalg

from dqcontrol.controllers.backends.osqp import OsqpBackend, osqp_setting_names
from dqcontrol.controllers.core.problem import BlockQP, DenseQP
from dqcontrol.errors import ParameterError


def _quadprog(qp: DenseQP) -> np.ndarray:
    """The optimum by quadprog (rows with two finite sides given as two inequalities)."""
    a, lo, up = qp.A, qp.lower, qp.upper
    keep_lo, keep_up = np.isfinite(lo), np.isfinite(up)
    c_mat = np.vstack([a[keep_lo], -a[keep_up]]).T
    b = np.concatenate([lo[keep_lo], -up[keep_up]])
    return quadprog.solve_qp(qp.P, -qp.c, c_mat, b)[0]


def _random_qp(rng: np.random.Generator, n: int = 8, rows: int = 4) -> DenseQP:
    g = rng.standard_normal((n + 2, n))
    p_mat = g.T @ g + 0.1 * np.eye(n)
    a = np.vstack([np.eye(n), rng.standard_normal((rows, n))])
    lower = np.concatenate([-np.ones(n), -1.0 - rng.random(rows)])
    upper = np.concatenate([np.ones(n), 1.0 + rng.random(rows)])
    return DenseQP(p_mat, 3.0 * rng.standard_normal(n), a, lower, upper)


@pytest.mark.parametrize("seed", range(4))
def test_dense_qps_reach_quadprogs_optimum(seed):
    rng = np.random.default_rng(seed)
    backend, qp = OsqpBackend(), _random_qp(rng)
    for k in range(3):  # the same rows, new values: the workspace is reused
        if k:
            qp = qp._replace(c=3.0 * rng.standard_normal(8))
        sol = backend.solve("level", qp)
        assert sol.ok and sol.status == "solved", sol.status
        np.testing.assert_allclose(sol.x, _quadprog(qp), atol=1e-8)


def test_block_qps_reach_quadprogs_optimum():
    rng = np.random.default_rng(9)
    p, m = 3, 4
    g = rng.standard_normal((p, m + 2, m))
    hessian = np.einsum("pki,pkj->pij", g, g) + 0.1 * np.eye(m)
    c_rows = rng.standard_normal((2, p * m))
    lower = np.concatenate([-0.5 * np.ones(p * m), [-1.0, -1.0]])
    upper = np.concatenate([0.5 * np.ones(p * m), [1.0, 1.0]])
    qp = BlockQP(hessian, 2.0 * rng.standard_normal(p * m), c_rows, lower, upper, structure=1)
    sol = OsqpBackend().solve_blocks(qp)
    assert sol.ok
    dense = qp.dense()
    np.testing.assert_allclose(dense.P, scipy.linalg.block_diag(*hessian))
    np.testing.assert_allclose(sol.x, _quadprog(dense), atol=1e-8)


def test_crossed_bounds_are_refused_before_osqp_sees_them():
    qp = _random_qp(np.random.default_rng(3))
    lower = qp.lower.copy()
    lower[2] = 2.0  # above its upper bound
    sol = OsqpBackend().solve(0, qp._replace(lower=lower))
    assert not sol.ok and sol.status.startswith("invalid_bounds") and "[2]" in sol.status


def test_unknown_settings_are_refused_and_ours_are_known():
    names = osqp_setting_names()
    assert {"max_iter", "eps_abs", "refine", "hot_start"} <= names
    with pytest.raises(ParameterError, match="solver_settings rejected by OSQP"):
        OsqpBackend({"no_such_setting": 1})
