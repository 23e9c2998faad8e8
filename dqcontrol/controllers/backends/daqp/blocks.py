"""DAQP (a dual active-set solver for dense QPs): the default backend of the QP
controllers (docs/theory.md §6, §7.5).

The controllers' QPs are small and dense per block (p (n+1) variables), and an active-set
method solves them exactly in a few iterations where a first-order method needs hundreds;
the workspace is set up once (:class:`daqp.Model`) and later steps only update ``H``, ``f``
and the bounds, starting from the previous step's active set.

As a backend (:meth:`DaqpBlocks.solve_blocks`) it specialises on the structure of the
:class:`~dqcontrol.controllers.core.problem.BlockQP` it is given, and sets its workspace up
again whenever that structure changes:

- one block and no general row (the local controller): DAQP's own dense form, the whole
  ``H`` handed over at every step (:meth:`DaqpBlocks.solve_dense`);
- several blocks or general rows (the predictive controllers): a new ``H`` would cost DAQP
  a dense factorisation, cubic in p (n+1), so the QP goes over as the equivalent
  least-distance problem (:mod:`~dqcontrol.controllers.backends.daqp.least_distance`), whose
  ``H`` never changes; the problem as it is where a block is not positive definite.
"""

from __future__ import annotations

import math
from ctypes import c_int
from functools import cache
from time import perf_counter

import numpy as np
import scipy.sparse as sp

from dqcontrol._compiled import compiled
from dqcontrol.controllers.backends.base import refused_bounds
from dqcontrol.controllers.backends.daqp.least_distance import block_ldp, ldp_solution
from dqcontrol.controllers.core.problem import BlockQP, Solution
from dqcontrol.controllers.core.task_kernels import scatter_blocks, scatter_symmetric
from dqcontrol.errors import ParameterError

__all__ = ["DaqpBlocks", "daqp_setting_names"]


@cache
def daqp_setting_names() -> frozenset[str]:
    """Names of DAQP's settings (empty if the package is missing)."""
    try:
        import daqp
    except ImportError:
        return frozenset()
    return frozenset(daqp.Model().settings)


_EXIT = {1: "solved", 2: "solved", -1: "primal_infeasible", -2: "cycling", -3: "unbounded",
         -4: "iteration_limit", -5: "nonconvex", -6: "initial_active_set_infeasible"}  # fmt: skip


def _kept(c: np.ndarray) -> np.ndarray | None:
    """``c`` if DAQP keeps this very array as its ``f`` (C-contiguous float64: the wrapper
    then stores no copy), else ``None``."""
    return c if (c.dtype == np.float64 and c.flags.c_contiguous) else None


_REFUSED = "error: DAQP refused the update"
_new_solution = tuple.__new__  # a NamedTuple from all its fields


@compiled
def bounds_state(lower: np.ndarray, upper: np.ndarray) -> int:
    """0: every row has ``-1e30 ≤ lower ≤ upper ≤ 1e30``; 1: consistent, but some bound
    beyond ±1e30 (to be clamped: DAQP's infinity); -1: some ``lower > upper`` or NaN."""
    state = 0
    for k in range(lower.shape[0]):
        lo, up = lower[k], upper[k]
        if not lo <= up:
            return -1
        if lo < -1e30 or up > 1e30:
            state = 1
    return state


class DaqpBlocks:
    """DAQP with its structure set once and values updated at every step.

    The first ``n`` rows of ``A`` must be the identity (bounds on the variables, as in the
    controllers); the remaining rows are general constraints. ``equality_rows`` (indices
    or a boolean mask) names the rows that are equalities by design (``lower == upper`` at
    every solve, e.g. ``s ≡ 1`` without time scaling): DAQP fixes those for the life of its
    workspace. Every other row is an inequality, even when a solve happens to give it
    ``lower == upper`` (a joint braking at a conflict): marked as an equality at setup, it
    would stay pinned after its bounds widen again, and DAQP would report that wrong
    optimum as solved.

    ``block_size`` declares ``P`` block diagonal with blocks of that size: each solve then
    hands DAQP the equivalent least-distance problem
    (:mod:`~dqcontrol.controllers.backends.daqp.least_distance`; DAQP's ``H`` stays the
    identity, so a new ``P`` costs no dense refactorisation), and falls back to the
    problem as it is where a block is not positive definite. Both give the same optimum
    (to ~1e-11 here).

    Constructed without ``p_pattern``, the structure comes from the first
    :meth:`solve_blocks` (the controllers' use: a backend, docs/theory.md §7.5).
    """

    name = "daqp"
    #: :meth:`solve_blocks` ignores :attr:`BlockQP.warm` (the active set is the warm start).
    uses_warm_start = False

    def __init__(
        self,
        p_pattern: sp.csc_matrix | None = None,
        a_matrix: sp.csc_matrix | None = None,
        settings: dict | None = None,
        equality_rows: np.ndarray | None = None,
        block_size: int | None = None,
    ) -> None:
        import daqp  # optional dependency, imported only when chosen

        self._daqp = daqp
        self.settings = dict(settings or {})
        known = daqp.Model().settings
        unknown = sorted(set(self.settings) - set(known))
        if unknown:
            raise ParameterError(
                f"solver_settings: DAQP has no setting {unknown}; it knows {sorted(known)}"
            )
        self.last_method = "daqp"
        self._structure: int | None = None
        self._values = 0
        self._box = False
        self._model = None
        self._block = 0
        if p_pattern is not None:
            self._configure(p_pattern, a_matrix, equality_rows, block_size)

    def _configure(
        self,
        p_pattern: sp.csc_matrix,
        a_matrix: sp.csc_matrix,
        equality_rows: np.ndarray | None,
        block_size: int | None,
    ) -> None:
        """Set the structure (and forget any workspace)."""
        self.p_pattern = sp.csc_matrix(p_pattern)
        self.p_pattern.sort_indices()
        self.a_matrix = sp.csc_matrix(a_matrix)
        self.num_vars = self.p_pattern.shape[0]
        self.num_cons = self.a_matrix.shape[0]
        a_dense = self.a_matrix.toarray()
        nv = self.num_vars
        if not np.array_equal(a_dense[:nv], np.eye(nv)):
            raise ParameterError(
                "DaqpBlocks needs A = [I; A_general] (bounds on the variables first)"
            )
        self._a_general = np.ascontiguousarray(a_dense[nv:])
        pat = self.p_pattern.tocoo()
        self._rows, self._cols = pat.row.astype(np.int64), pat.col.astype(np.int64)
        self._h = np.zeros((nv, nv))
        self._sense = np.zeros(self.num_cons, dtype=c_int)
        if equality_rows is not None:
            self._sense[np.asarray(equality_rows)] = 5  # DAQP: active and immutable
        self._model = None
        self._f_given: np.ndarray | None = None  # the f DAQP holds (not a copy of)
        self._block = 0
        self._ldp_model = None
        if block_size is not None:
            self._setup_blocks(int(block_size))

    def _setup_blocks(self, block: int) -> None:
        """Check that ``P``'s pattern is block diagonal and allocate the least-distance
        problem's buffers (DAQP holds them: they live as long as this object)."""
        nv = self.num_vars
        if block < 1 or nv % block or np.any(self._rows // block != self._cols // block):
            raise ParameterError(
                f"block_size={block}: P ({nv} variables) is not block diagonal with blocks "
                f"of that size"
            )
        general = sp.csr_matrix(self.a_matrix[nv:])
        self._a_ptr = general.indptr.astype(np.int64)
        self._a_idx = general.indices.astype(np.int64)
        self._a_val = general.data.astype(float)
        self._m_buf = np.zeros((self.num_cons, nv))
        self._lo_buf = np.zeros(self.num_cons)
        self._up_buf = np.zeros(self.num_cons)
        self._linv_t = np.zeros((nv // block, block, block))
        self._w = np.zeros(nv)
        self._eye = np.eye(nv)
        self._zero_f = np.zeros(nv)
        self._ldp_model = None
        self._block = block

    def reset(self) -> None:
        """Forget the workspace and the active set."""
        self._model = None
        if self._block:
            self._ldp_model = None

    def solve(
        self,
        p_values: np.ndarray,
        c: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        warm_x: np.ndarray | None = None,
    ) -> Solution:
        """Update the values and solve (warm start: the previous active set)."""
        start = perf_counter()
        if not (lower <= upper).all():  # also catches NaN
            return refused_bounds(lower, upper, start)
        scatter_symmetric(self._h, self._rows, self._cols, p_values)  # compiled
        x, ok, status, iterations = self._solve_h(c, lower, upper)
        return Solution(ok, status, iterations, perf_counter() - start, x)

    def _solve_h(
        self, c: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> tuple[np.ndarray | None, bool, str, int]:
        """Solve with the ``H`` in ``self._h`` (checked bounds): the least-distance form
        where it applies, else the problem as it is."""
        h = self._h
        if self._block and block_ldp(
            h, self._block, c, lower, upper, self._a_ptr, self._a_idx, self._a_val,
            self._m_buf, self._lo_buf, self._up_buf, self._linv_t, self._w,
        ):  # fmt: skip
            self.last_method = "least_distance"
            return self._solve_ldp()
        self.last_method = "daqp"
        lo = np.maximum(lower, -1e30)
        up = np.minimum(upper, 1e30)
        return self._solve(h, c, lo, up)

    def solve_blocks(self, qp: BlockQP) -> Solution:
        """Solve a :class:`~dqcontrol.controllers.core.problem.BlockQP`, the workspace set up for
        its structure (one block without general rows: the dense form; otherwise the
        least-distance one). Never raises for a failed solve: the solution says so."""
        start = perf_counter()
        hessian = qp.hessian
        if qp.structure != self._structure:  # the number names the shapes too
            self._configure_blocks(qp)
            self._structure = qp.structure
            self._values = qp.values
        elif qp.values != self._values:  # same shapes, new values of C
            self._refresh_general(qp.C)
            self._values = qp.values
        lower, upper = qp.lower, qp.upper
        if self._box:
            state = bounds_state(lower, upper)  # compiled: 0 usable, 1 clamp, -1 refused
            if state < 0:
                return refused_bounds(lower, upper, start)
            if state > 0:
                lower, upper = np.maximum(lower, -1e30), np.minimum(upper, 1e30)
            model = self._model
            if model is not None and qp.c is self._f_given:
                # the usual step, as solve_dense (written out: it runs at 1 kHz)
                try:
                    if model.update(H=hessian[0], bupper=upper, blower=lower) < 0:
                        self._model = None
                        return Solution(False, _REFUSED, 0, perf_counter() - start)
                    x, _fval, flag, info = model.solve()
                except Exception as exc:  # noqa: BLE001 - never stop the control loop
                    self._model = None
                    return Solution(False, f"error: {exc}", 0, perf_counter() - start)
                if (flag == 1 or flag == 2) and x is not None and math.isfinite(x.dot(x)):
                    iterations = info.get("iterations", 0) if isinstance(info, dict) else 0
                    return _new_solution(
                        Solution,
                        (True, "solved", int(iterations), perf_counter() - start, x, None),
                    )
                x, ok, status, iterations = _outcome(x, flag, info)
                if not ok:
                    self._model = None
            else:
                x, ok, status, iterations = self._solve(hessian[0], qp.c, lower, upper)
            return _new_solution(
                Solution, (ok, status, iterations, perf_counter() - start, x, None)
            )
        if not (lower <= upper).all():  # also catches NaN
            return refused_bounds(lower, upper, start)
        scatter_blocks(self._h, hessian)  # compiled: the diagonal blocks of H
        x, ok, status, iterations = self._solve_h(qp.c, lower, upper)
        return Solution(ok, status, iterations, perf_counter() - start, x)

    def _refresh_general(self, general: np.ndarray) -> None:
        """New values of the general rows ``C`` (same shape): the dense copy and the
        least-distance form's sparse arrays, without setting the workspace up again."""
        self._a_general = np.ascontiguousarray(general)
        self._model = None  # the dense form's workspace holds the old rows: set up anew
        if self._block:
            rows, cols = np.nonzero(general)
            self._a_ptr = np.searchsorted(rows, np.arange(general.shape[0] + 1)).astype(np.int64)
            self._a_idx = cols.astype(np.int64)
            self._a_val = general[rows, cols].astype(float)

    @property
    def form(self) -> str:
        """The form DAQP gets: ``"dense"`` (the problem as it is) or ``"least_distance"``."""
        return "least_distance" if self._block else "dense"

    def _configure_blocks(self, qp: BlockQP) -> None:
        """The structure of ``qp``: ``P`` block diagonal, ``A = [I; C]``, the fixed
        variables as equalities; the least-distance form unless one block and no row."""
        p, m, _ = qp.hessian.shape
        rows = qp.C.shape[0]
        block = sp.csc_matrix(np.triu(np.ones((m, m))))
        pattern = sp.block_diag([block] * p, format="csc")
        a_rows = [sp.identity(p * m, format="csc")]
        if rows:
            a_rows.append(sp.csc_matrix(qp.C))
        fixed = np.array(qp.fixed, dtype=np.int64) if qp.fixed else None
        self._box = p == 1 and rows == 0
        self._configure(pattern, sp.vstack(a_rows, format="csc"), fixed, None if self._box else m)

    def solve_dense(
        self, h: np.ndarray, c: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> tuple[np.ndarray | None, bool, str, int, float]:
        """:meth:`solve` for a caller that has the whole ``H`` and checked bounds: the
        single-block form of :meth:`solve_blocks` (a tuple, no
        :class:`~dqcontrol.controllers.core.problem.Solution`).

        ``h`` is the full symmetric ``H`` (C-contiguous; DAQP keeps it until the next
        update: do not write to it afterwards). The caller guarantees what :meth:`solve`
        checks and clamps: ``-1e30 ≤ lower ≤ upper ≤ 1e30`` in every row, no NaN (bounds
        that fail it must go through :meth:`solve`, which refuses them as
        ``invalid_bounds``). Returns ``(x, ok, status, iterations, solve_time_s)``, ``x``
        ``None`` unless ``ok``.
        """
        start = perf_counter()
        model = self._model
        if model is None or c is not self._f_given:
            x, ok, status, iterations = self._solve(h, c, lower, upper)
            return x, ok, status, iterations, perf_counter() - start
        # the usual step, as _solve() with the same f: written out here (this path runs at
        # 1 kHz and every Python call counts)
        try:
            if model.update(H=h, bupper=upper, blower=lower) < 0:
                self._model = None
                return None, False, _REFUSED, 0, perf_counter() - start
            x, _fval, flag, info = model.solve()
        except Exception as exc:  # noqa: BLE001 - never stop the control loop
            self._model = None
            return None, False, f"error: {exc}", 0, perf_counter() - start
        if (flag == 1 or flag == 2) and x is not None and math.isfinite(x.dot(x)):
            iterations = info.get("iterations", 0) if isinstance(info, dict) else 0
            return x, True, "solved", int(iterations), perf_counter() - start
        x, ok, status, iterations = _outcome(x, flag, info)
        if not ok:
            self._model = None
        return x, ok, status, iterations, perf_counter() - start

    def _solve(
        self,
        h: np.ndarray,
        c: np.ndarray,
        lo: np.ndarray,
        up: np.ndarray,
    ) -> tuple[np.ndarray | None, bool, str, int]:
        """Update DAQP's workspace (set it up on the first call) and solve: ``(x, ok,
        status, iterations)``."""
        model = self._model
        try:
            if model is None:
                model = self._daqp.Model()
                model.setup(h, c, self._a_general, up, lo, self._sense.copy())
                if self.settings:
                    model.settings = dict(self.settings)
                self._model = model
                self._f_given = _kept(c)
            elif c is self._f_given:
                # DAQP keeps the f it was given (not a copy) and recomputes its own terms
                # from it whenever H changes: the same f need not be passed again
                if model.update(H=h, bupper=up, blower=lo) < 0:
                    self._model = None
                    return None, False, _REFUSED, 0
            else:
                if model.update(H=h, f=c, bupper=up, blower=lo) < 0:
                    self._model = None
                    return None, False, _REFUSED, 0
                self._f_given = _kept(c)
            x, _fval, flag, info = model.solve()
        except Exception as exc:  # noqa: BLE001 - never stop the control loop
            self._model = None
            return None, False, f"error: {exc}", 0
        x, ok, status, iterations = _outcome(x, flag, info)
        if not ok:
            self._model = None  # rebuilt at the next solve
        return x, ok, status, iterations

    def _solve_ldp(self) -> tuple[np.ndarray | None, bool, str, int]:
        """Solve the least-distance problem :func:`block_ldp` has just written (DAQP with
        ``H = I`` for the life of the workspace; later steps update ``M`` and the bounds
        only) and map its solution back: ``(x, ok, status, iterations)``."""
        model = self._ldp_model
        try:
            if model is None:
                model = self._daqp.Model()
                model.setup(
                    self._eye, self._zero_f, self._m_buf, self._up_buf, self._lo_buf,
                    self._sense.copy(),
                )  # fmt: skip
                if self.settings:
                    model.settings = dict(self.settings)
                self._ldp_model = model
            elif model.update(A=self._m_buf, bupper=self._up_buf, blower=self._lo_buf) < 0:
                self._ldp_model = None
                return None, False, _REFUSED, 0
            u, _fval, flag, info = model.solve()
        except Exception as exc:  # noqa: BLE001 - never stop the control loop
            self._ldp_model = None
            return None, False, f"error: {exc}", 0
        u, ok, status, iterations = _outcome(u, flag, info)
        if not ok or u is None:  # x is None unless ok
            self._ldp_model = None
            return None, False, status, iterations
        return ldp_solution(self._linv_t, u, self._w), True, status, iterations


def _outcome(
    x: np.ndarray | None, flag: int, info: object
) -> tuple[np.ndarray | None, bool, str, int]:
    """``(x, ok, status, iterations)`` of DAQP's answer (``x`` ``None`` unless ok); the
    caller forgets the workspace that gave a failed answer."""
    # x is a new array at every solve; a dot product is NaN/inf iff some entry is (or it
    # overflows): the cheap test first
    ok = (
        (flag == 1 or flag == 2)
        and x is not None
        and (math.isfinite(x.dot(x)) or bool(np.isfinite(x).all()))
    )
    status = "solved" if flag == 1 or flag == 2 else _EXIT.get(int(flag), f"daqp_exit_{flag}")
    iterations = int(info.get("iterations", 0)) if isinstance(info, dict) else 0
    return (x if ok else None), ok, status, iterations
