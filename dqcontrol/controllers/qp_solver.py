"""OSQP behind a small interface: structure once, values every step, warm-started.

The controllers describe their QP as ``minimize ½ zᵀ P z + cᵀ z  s.t.  l ≤ A z ≤ u`` with
a *fixed* sparsity pattern; :class:`OsqpQP` sets OSQP up once and afterwards only updates
the value arrays (``P``'s upper-triangle values, ``c``, ``l``, ``u``) in place.

Settings: tolerances 1e-9 absolute/relative (the thesis blamed solver noise for jitter;
at these tolerances the command is exact to well below a µrad/s), adaptive ρ, no
*polishing*: OSQP 1.x prints an unguarded line on every polished solve without an active
set (osqp/osqp#785) and its polish may accept a worse point (osqp/osqp#790).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

__all__ = ["DEFAULT_OSQP_SETTINGS", "OsqpQP", "QPSolution"]

DEFAULT_OSQP_SETTINGS: dict = {
    "eps_abs": 1e-9,
    "eps_rel": 1e-9,
    "eps_prim_inf": 1e-7,
    "eps_dual_inf": 1e-7,
    "max_iter": 20000,
    "polishing": False,
    "adaptive_rho": True,
    "warm_starting": True,
    "check_termination": 10,
    "verbose": False,
}

_SUCCESS = {osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE}


@dataclass(frozen=True)
class QPSolution:
    """Result of one solve: ``x`` is ``None`` unless ``ok``."""

    x: np.ndarray | None
    y: np.ndarray | None
    ok: bool
    status: str
    iterations: int
    solve_time_s: float


class OsqpQP:
    """An OSQP problem whose structure is fixed at construction.

    Args:
        p_pattern: upper-triangular sparse matrix giving the structure of ``P`` (CSC).
        a_matrix: constraint matrix ``A`` (its values are constant here).
        settings: OSQP settings overriding :data:`DEFAULT_OSQP_SETTINGS`.
    """

    def __init__(
        self, p_pattern: sp.csc_matrix, a_matrix: sp.csc_matrix, settings: dict | None = None
    ) -> None:
        self.p_pattern = sp.csc_matrix(p_pattern)
        self.p_pattern.sort_indices()
        self.a_matrix = sp.csc_matrix(a_matrix)
        self.a_matrix.sort_indices()
        self.num_vars = self.p_pattern.shape[0]
        self.num_cons = self.a_matrix.shape[0]
        self.settings = dict(DEFAULT_OSQP_SETTINGS)
        if settings:
            self.settings.update(settings)
        self._solver: osqp.OSQP | None = None
        self._p_values = np.zeros(self.p_pattern.nnz)
        self._p_changed = True

    @property
    def p_nnz(self) -> int:
        """Number of stored values of ``P`` (upper triangle, CSC order)."""
        return self.p_pattern.nnz

    def _setup(self, p_values: np.ndarray, c: np.ndarray, lower: np.ndarray, upper: np.ndarray):
        p = sp.csc_matrix(
            (p_values, self.p_pattern.indices, self.p_pattern.indptr), shape=self.p_pattern.shape
        )
        solver = osqp.OSQP()
        solver.setup(P=p, q=c, A=self.a_matrix, l=lower, u=upper, **self.settings)
        self._solver = solver

    def solve(
        self,
        p_values: np.ndarray,
        c: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        warm_x: np.ndarray | None = None,
    ) -> QPSolution:
        """Update the values and solve. Never raises for a failed solve: check ``ok``."""
        start = time.perf_counter()
        try:
            if self._solver is None:
                self._setup(p_values, c, lower, upper)
            else:
                self._solver.update(Px=p_values, q=c, l=lower, u=upper)
            if warm_x is not None:
                self._solver.warm_start(x=warm_x)
            res = self._solver.solve(raise_error=False)
        except Exception as exc:  # noqa: BLE001 - a solver failure must not stop the loop
            self._solver = None  # rebuild next time
            return QPSolution(None, None, False, f"error: {exc}", 0, time.perf_counter() - start)
        status = res.info.status_val
        ok = status in _SUCCESS and res.x is not None and bool(np.all(np.isfinite(res.x)))
        return QPSolution(
            x=np.array(res.x) if ok else None,
            y=np.array(res.y) if ok else None,
            ok=ok,
            status=str(res.info.status),
            iterations=int(res.info.iter),
            solve_time_s=time.perf_counter() - start,
        )

    def reset(self) -> None:
        """Forget the factorisation and warm start (next solve sets OSQP up again)."""
        self._solver = None
