"""DAQP (a dual active-set solver for dense QPs) behind the interface of :class:`OsqpQP`.

The default backend (``solver="daqp"``; OSQP stays selectable with ``solver="osqp"``).
The controllers' QPs are small and dense per block (p (n+1) variables), and an active-set
method solves them exactly in a few iterations where a first-order method needs hundreds;
the workspace is set up once (:class:`daqp.Model`) and later steps only update ``H``, ``f``
and the bounds, starting from the previous step's active set. Its cost is DAQP's dense
factorisation of ``H`` at every update, cubic in p (n+1) (docs/performance.md).
``dqcontrol bench`` compares the two backends.
"""

from __future__ import annotations

import math
import time
from ctypes import c_int
from functools import cache

import numpy as np
import scipy.sparse as sp

from dqcontrol.controllers.qp_solver import QPSolution, invalid_bounds
from dqcontrol.errors import ParameterError

__all__ = ["DaqpQP", "daqp_setting_names"]


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


class DaqpQP:
    """Same contract as :class:`~dqcontrol.controllers.qp_solver.OsqpQP`.

    The first ``n`` rows of ``A`` must be the identity (bounds on the variables, as in the
    controllers); the remaining rows are general constraints.
    """

    def __init__(
        self, p_pattern: sp.csc_matrix, a_matrix: sp.csc_matrix, settings: dict | None = None
    ) -> None:
        import daqp  # optional dependency, imported only when chosen

        self._daqp = daqp
        self.p_pattern = sp.csc_matrix(p_pattern)
        self.p_pattern.sort_indices()
        self.a_matrix = sp.csc_matrix(a_matrix)
        self.num_vars = self.p_pattern.shape[0]
        self.num_cons = self.a_matrix.shape[0]
        a_dense = self.a_matrix.toarray()
        nv = self.num_vars
        if not np.array_equal(a_dense[:nv], np.eye(nv)):
            raise ParameterError("DaqpQP needs A = [I; A_general] (bounds on the variables first)")
        self._a_general = np.ascontiguousarray(a_dense[nv:])
        pat = self.p_pattern.tocoo()
        self._rows, self._cols = pat.row, pat.col
        self._h = np.zeros((nv, nv))
        self.settings = dict(settings or {})
        known = daqp.Model().settings
        unknown = sorted(set(self.settings) - set(known))
        if unknown:
            raise ParameterError(
                f"solver_settings: DAQP has no setting {unknown}; it knows {sorted(known)}"
            )
        self._model = None
        self.last_method = "daqp"

    def reset(self) -> None:
        """Forget the workspace and the active set."""
        self._model = None

    def solve(
        self,
        p_values: np.ndarray,
        c: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        warm_x: np.ndarray | None = None,
    ) -> QPSolution:
        """Update the values and solve (warm start: the previous active set)."""
        start = time.perf_counter()
        if not (lower <= upper).all():  # also catches NaN
            return invalid_bounds(lower, upper, start)
        h = self._h
        h[self._rows, self._cols] = p_values
        h[self._cols, self._rows] = p_values
        lo = np.maximum(lower, -1e30)
        up = np.minimum(upper, 1e30)
        try:
            if self._model is None:
                model = self._daqp.Model()
                sense = np.zeros(self.num_cons, dtype=c_int)
                sense[lower == upper] = 5
                model.setup(h, c, self._a_general, up, lo, sense)
                if self.settings:
                    model.settings = dict(self.settings)
                self._model = model
            elif self._model.update(H=h, f=c, bupper=up, blower=lo) < 0:
                self._model = None
                return QPSolution(
                    None, None, False, "error: DAQP refused the update", 0,
                    time.perf_counter() - start,
                )  # fmt: skip
            x, _fval, flag, info = self._model.solve()
        except Exception as exc:  # noqa: BLE001 - never stop the control loop
            self._model = None
            return QPSolution(None, None, False, f"error: {exc}", 0, time.perf_counter() - start)
        # x is a new array at every solve; a dot product is NaN/inf iff some entry is (or
        # it overflows): the cheap test first
        ok = (
            (flag == 1 or flag == 2)
            and x is not None
            and (math.isfinite(x.dot(x)) or bool(np.isfinite(x).all()))
        )
        if not ok:
            self._model = None
            x = None
        return QPSolution(
            x, None, ok, _EXIT.get(int(flag), f"daqp_exit_{flag}"),
            int(info.get("iterations", 0)) if isinstance(info, dict) else 0,
            time.perf_counter() - start,
        )  # fmt: skip
