"""OSQP behind a small interface: structure once, values every step, warm-started
(docs/theory.md §6, §7.5).

A QP ``minimize ½ zᵀ P z + cᵀ z  s.t.  l ≤ A z ≤ u`` with a *fixed* sparsity pattern:
:class:`OsqpWorkspace` sets OSQP up once and afterwards only updates the value arrays (``P``'s
upper-triangle values, ``c``, ``l``, ``u``) in place. As a backend
(:meth:`OsqpWorkspace.solve_blocks`) it takes the structure from the
:class:`~dqcontrol.controllers.core.problem.BlockQP` it is given (block-diagonal ``P``,
``A = [I; C]``) and sets OSQP up again whenever that structure changes.

Settings: tolerances 1e-9 absolute/relative, adaptive ρ, no OSQP *polishing*: OSQP 1.x
prints an unguarded line on every polished solve without an active set (osqp/osqp#785) and
its polish may accept a worse point (osqp/osqp#790); on our problems it failed often.

Exactness (*refinement*, on by default). The controllers' costs are nearly singular in the
robot's redundant direction (only ``μ ≈ 1e-6`` fixes it), where a first-order method stops
~1e-4 rad/s away from the optimum without seeing any residual — the solver noise the thesis
blamed for jitter. After OSQP converges, :class:`OsqpWorkspace` takes the active set it found
(rows at a bound with a non-zero multiplier, and equalities), solves that
equality-constrained KKT system exactly, and keeps the result only if it is primal
feasible and its multipliers have the right signs (i.e. it *is* the optimum); otherwise it
keeps OSQP's point. The applied command then matches an independent active-set solver to
~1e-10.
"""

from __future__ import annotations

import time
from functools import cache

import numpy as np
import osqp
import scipy.sparse as sp

from dqcontrol.controllers.backends.base import Backend, invalid_bounds
from dqcontrol.controllers.core.problem import BlockQP, DenseQP, Solution
from dqcontrol.errors import ParameterError

__all__ = ["DEFAULT_OSQP_SETTINGS", "OsqpBackend", "OsqpWorkspace", "osqp_setting_names"]

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


@cache
def osqp_setting_names() -> frozenset[str]:
    """Names of OSQP's settings, and of ours (``refine``, ``hot_start``)."""
    return frozenset(DEFAULT_OSQP_SETTINGS) | {
        "refine", "hot_start", "time_limit", "rho", "sigma", "alpha", "delta", "scaling",
        "scaled_termination", "polish_refine_iter", "linsys_solver", "adaptive_rho_interval",
        "adaptive_rho_tolerance", "adaptive_rho_fraction", "rho_is_vec", "allocate_solution",
        "cg_max_iter", "cg_tol_reduction", "cg_tol_fraction", "cg_precond", "device",
    }  # fmt: skip


def _check_osqp_settings(settings: dict) -> None:
    """Refuse settings OSQP does not know (or values it rejects) at construction."""
    probe = osqp.OSQP()
    try:
        probe.setup(
            P=sp.csc_matrix(np.eye(1)),
            q=np.zeros(1),
            A=sp.csc_matrix(np.eye(1)),
            l=-np.ones(1),
            u=np.ones(1),
            **settings,
        )
    except (TypeError, ValueError) as exc:
        known = ", ".join(sorted(DEFAULT_OSQP_SETTINGS) + ["hot_start", "refine"])
        raise ParameterError(
            f"solver_settings rejected by OSQP: {exc} (settings we set: {known}; see OSQP's "
            "documentation for the others)"
        ) from None


class OsqpWorkspace:
    """An OSQP problem whose structure is fixed at construction (or by the first
    :meth:`solve_blocks`).

    Args:
        p_pattern: upper-triangular sparse matrix giving the structure of ``P`` (CSC).
        a_matrix: constraint matrix ``A`` (its values are constant here).
        settings: OSQP settings overriding :data:`DEFAULT_OSQP_SETTINGS`.
    """

    name = "osqp"
    #: :meth:`solve_blocks` starts OSQP from :attr:`BlockQP.warm` when given.
    uses_warm_start = True

    def __init__(
        self,
        p_pattern: sp.csc_matrix | None = None,
        a_matrix: sp.csc_matrix | None = None,
        settings: dict | None = None,
    ) -> None:
        self.settings = dict(DEFAULT_OSQP_SETTINGS)
        if settings:
            self.settings.update(settings)
        self.refine = bool(self.settings.pop("refine", True))
        self.hot_start = bool(self.settings.pop("hot_start", True))
        _check_osqp_settings(self.settings)
        self.last_method = ""
        self._structure: tuple | None = None
        self._solver: osqp.OSQP | None = None
        self._active: tuple[np.ndarray, np.ndarray] | None = None
        if p_pattern is not None:
            self._configure(p_pattern, a_matrix)

    def _configure(self, p_pattern: sp.csc_matrix, a_matrix: sp.csc_matrix) -> None:
        """Set the structure (and forget the workspace)."""
        self.p_pattern = sp.csc_matrix(p_pattern)
        self.p_pattern.sort_indices()
        self.a_matrix = sp.csc_matrix(a_matrix)
        self.a_matrix.sort_indices()
        self.num_vars = self.p_pattern.shape[0]
        self.num_cons = self.a_matrix.shape[0]
        self._solver = None
        self._active = None
        # dense views for the refinement
        pat = self.p_pattern.tocoo()
        self._p_rows, self._p_cols = pat.row, pat.col
        self._a_dense = self.a_matrix.toarray()

    def solve_blocks(self, qp: BlockQP) -> Solution:
        """Solve a :class:`~dqcontrol.controllers.core.problem.BlockQP` (OSQP set up for its
        structure: ``P``'s stored values are the blocks' upper triangles)."""
        p, m, _ = qp.hessian.shape
        key = (qp.hessian.shape, qp.structure, qp.values)  # OSQP's A is set up with it
        if key != self._structure:
            block = sp.csc_matrix(np.triu(np.ones((m, m))))
            a_rows = [sp.identity(p * m, format="csc")]
            if qp.C.shape[0]:
                a_rows.append(sp.csc_matrix(qp.C))
            self._configure(
                sp.block_diag([block] * p, format="csc"), sp.vstack(a_rows, format="csc")
            )
            # CSC order of each block's upper triangle in the flattened (p, m, m) blocks
            cols, rows = np.triu_indices(m)[::-1]
            order = np.lexsort((rows, cols))
            within = rows[order] * m + cols[order]
            self._gather = (np.arange(p)[:, None] * m * m + within[None, :]).ravel()
            self._structure = key
        return self.solve(qp.hessian.ravel()[self._gather], qp.c, qp.lower, qp.upper, qp.warm)

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
    ) -> Solution:
        """Update the values and solve. Never raises for a failed solve: check ``ok``.

        With ``hot_start`` (default), the previous step's active set is tried first: one
        KKT solve, accepted only if verified optimal (primal feasible, multipliers of the
        right sign), which is the usual case in a control loop where the active set changes
        rarely. Otherwise OSQP solves (warm-started) and its result is refined.
        """
        start = time.perf_counter()
        refused = invalid_bounds(lower, upper, start)
        if refused is not None:
            self._active = None
            return refused
        if self.hot_start and self._active is not None:
            guess = self._kkt(p_values, c, lower, upper, *self._active)
            if guess is not None:
                self.last_method = "hot_start"
                return Solution(True, "solved", 0, time.perf_counter() - start, guess)
        try:
            if self._solver is None:
                self._setup(p_values, c, lower, upper)
            else:
                self._solver.update(Px=p_values, q=c, l=lower, u=upper)
            solver = self._solver
            assert solver is not None, "set up above"
            if warm_x is not None:
                solver.warm_start(x=warm_x)
            res = solver.solve(raise_error=False)
        except Exception as exc:  # noqa: BLE001 - a solver failure must not stop the loop
            self._solver = None  # rebuild next time
            self._active = None
            return Solution(False, f"error: {exc}", 0, time.perf_counter() - start)
        status = res.info.status_val
        ok = status in _SUCCESS and res.x is not None and bool(np.all(np.isfinite(res.x)))
        x = np.array(res.x) if ok else None
        self.last_method = "osqp"
        self._active = None
        if ok and self.refine:
            x = self._refined(x, np.asarray(res.y), p_values, c, lower, upper)
        return Solution(
            ok=ok,
            status=str(res.info.status),
            iterations=int(res.info.iter),
            solve_time_s=time.perf_counter() - start,
            x=x,
            duals=np.array(res.y) if ok else None,
        )

    def _refined(self, x, y, p_values, c, lower, upper) -> np.ndarray:
        """OSQP's ``x`` refined by one KKT solve on the rows its multipliers ``y`` hold at
        a bound (``last_method`` says so), or ``x`` as it is where that solve is refused."""
        ax = self._a_dense @ x
        scale = max(1.0, float(np.max(np.abs(y))))
        at_low = (ax - lower <= 1e-6) & (y < -1e-9 * scale)
        at_up = (upper - ax <= 1e-6) & (y > 1e-9 * scale)
        refined = self._kkt(p_values, c, lower, upper, at_low, at_up)
        if refined is None:
            return x
        self.last_method = "osqp+refine"
        return refined

    def _kkt(
        self,
        p_values: np.ndarray,
        c: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        at_low: np.ndarray,
        at_up: np.ndarray,
    ) -> np.ndarray | None:
        """Optimum with the rows ``at_low``/``at_up`` (and every equality) held at their
        bounds, or ``None`` if that point is not verified to be the QP's optimum."""
        eq = lower == upper
        low = at_low & ~eq
        up = at_up & ~eq
        act = low | up | eq
        bound = np.where(up, upper, lower)[act]
        if not np.all(np.isfinite(bound)):
            return None
        a = self._a_dense
        nv, na = self.num_vars, int(act.sum())
        kkt = np.zeros((nv + na, nv + na))
        kkt[self._p_rows, self._p_cols] = p_values
        kkt[self._p_cols, self._p_rows] = p_values
        a_act = a[act]
        kkt[nv:, :nv] = a_act
        kkt[:nv, nv:] = a_act.T
        rhs = np.concatenate((-c, bound))
        try:
            sol = np.linalg.solve(kkt, rhs)
        except np.linalg.LinAlgError:
            return None
        if not np.all(np.isfinite(sol)):
            return None
        xs, lam = sol[:nv], sol[nv:]
        axs = a @ xs
        tol = 1e-9 * max(1.0, float(np.max(np.abs(xs))))
        if np.any(axs < lower - tol) or np.any(axs > upper + tol):
            return None
        # optimality: P x + c + Aᵀλ = 0 with λ ≥ 0 on rows at their upper bound and λ ≤ 0 on
        # rows at their lower bound (OSQP's sign convention for y)
        scale = max(1.0, float(np.max(np.abs(lam)))) if na else 1.0
        if np.any(lam[up[act]] < -1e-9 * scale) or np.any(lam[low[act]] > 1e-9 * scale):
            return None
        self._active = (low, up)
        return xs

    def reset(self) -> None:
        """Forget the factorisation, the warm start and the active set."""
        self._solver = None
        self._active = None


class OsqpBackend(Backend):
    """OSQP (ADMM) refined to the exact optimum of the active set it finds: one
    :class:`OsqpWorkspace` per level ``key`` and sparsity pattern (dense patterns: values
    change freely), and one for the block-diagonal QPs of :meth:`solve_blocks`, started
    from the previous plan (:attr:`BlockQP.warm`).

    Args:
        settings: OSQP settings over :data:`DEFAULT_OSQP_SETTINGS` (and ``refine``,
            ``hot_start``); unknown ones are refused here.
    """

    name = "osqp"
    uses_warm_start = True

    def __init__(self, settings: dict | None = None) -> None:
        self.settings = dict(settings or {})
        self._blocks = OsqpWorkspace(settings=self.settings)
        self._qps: dict = {}

    def reset(self) -> None:
        """Forget every workspace."""
        self._blocks.reset()
        self._qps.clear()

    def solve_blocks(self, qp: BlockQP) -> Solution:
        """One level with a block-diagonal ``P`` (:meth:`OsqpWorkspace.solve_blocks`)."""
        return self._blocks.solve_blocks(qp)

    def solve(self, key: object, qp: DenseQP) -> Solution:
        """Solve level ``key``'s QP with OSQP, refined to the exact active set."""
        nv = qp.c.size
        entry = self._qps.get(key)
        if entry is None or entry[1] != qp.A.shape or not np.array_equal(entry[2], qp.A):
            pattern = sp.csc_matrix(np.triu(np.ones((nv, nv))))
            solver = OsqpWorkspace(pattern, sp.csc_matrix(qp.A), self.settings)
            self._qps[key] = (solver, qp.A.shape, qp.A.copy())
        solver = self._qps[key][0]
        rows, cols = np.triu_indices(nv)
        order = np.lexsort((rows, cols))  # CSC order of the upper triangle
        return solver.solve(qp.P[rows[order], cols[order]], qp.c, qp.lower, qp.upper)
