"""OSQP on dense QPs, refined to the exact optimum of the active set it finds
(docs/theory.md §7.5)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from dqcontrol.controllers.problem import DenseQP, Solution
from dqcontrol.controllers.qp_solver import OsqpQP

__all__ = ["OsqpBackend"]


class OsqpBackend:
    """OSQP (ADMM) with the active-set refinement of :class:`OsqpQP`; one workspace per key
    and sparsity pattern (dense patterns here: values change freely)."""

    name = "osqp"

    def __init__(self, settings: dict | None = None) -> None:
        self.settings = dict(settings or {})
        self._qps: dict = {}

    def reset(self) -> None:
        """Forget every level's workspace."""
        self._qps.clear()

    def solve(self, key: object, qp: DenseQP) -> Solution:
        """Solve level ``key``'s QP with OSQP, refined to the exact active set."""
        nv = qp.c.size
        pattern = sp.csc_matrix(np.triu(np.ones((nv, nv))))
        a_sparse = sp.csc_matrix(qp.A)
        entry = self._qps.get(key)
        if entry is None or entry[1] != qp.A.shape or not np.array_equal(entry[2], qp.A):
            solver = OsqpQP(pattern, a_sparse, self.settings)
            self._qps[key] = (solver, qp.A.shape, qp.A.copy())
        solver = self._qps[key][0]
        rows, cols = np.triu_indices(nv)
        order = np.lexsort((rows, cols))  # CSC order of the upper triangle
        values = qp.P[rows[order], cols[order]]
        res = solver.solve(values, qp.c, qp.lower, qp.upper)
        return Solution(res.ok, res.status, res.iterations, res.solve_time_s, res.x, res.y)
