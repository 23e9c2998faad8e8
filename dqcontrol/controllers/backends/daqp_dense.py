"""DAQP on dense QPs: one workspace per problem (priority level), updated in place each
step (docs/theory.md §7.5).

A QP with a positive definite ``H`` and sparse general rows is handed to DAQP as the
equivalent least-distance problem (:func:`~dqcontrol.controllers.qp_ldp.dense_ldp`,
compiled), so that DAQP's ``H`` stays the identity for the workspace's life: forming
``C L⁻ᵀ`` then costs one pass over the non-zeros of ``C``, where DAQP, given the new ``H``,
would form ``A R⁻¹`` over every entry. With dense rows (a level reduced to the null space
of the levels above) DAQP's own handling costs the same and is kept.
"""

from __future__ import annotations

import time
from ctypes import c_int

import numpy as np

from dqcontrol.controllers.problem import DenseQP, Solution
from dqcontrol.controllers.qp_ldp import dense_ldp, ldp_solution
from dqcontrol.errors import ParameterError

__all__ = ["DaqpBackend"]

#: DAQP settings of this backend: tighter primal tolerance than DAQP's 1e-6, so that the
#: rows holding a higher level are met to within 1e-9.
DEFAULT_DAQP_SETTINGS = {"primal_tol": 1e-9}

_EXIT = {-1: "primal_infeasible", -2: "cycling", -3: "unbounded", -4: "iteration_limit",
         -5: "nonconvex", -6: "initial_active_set_infeasible"}  # fmt: skip
_BIG = 1e30
#: Largest share of non-zero entries in the general rows for the least-distance form.
SPARSE_ROWS_SHARE = 0.25


class DaqpBackend:
    """Dense DAQP (dual active set), warm-started from the previous active set per key.

    Args:
        settings: DAQP settings over :data:`DEFAULT_DAQP_SETTINGS`.
        least_distance: hand DAQP the least-distance form of QPs whose Hessian is positive
            definite and whose general rows are sparse (the same optimum, found cheaper);
            ``False`` gives DAQP every QP as it is.
    """

    name = "daqp"

    def __init__(self, settings: dict | None = None, least_distance: bool = True) -> None:
        import daqp

        self._daqp = daqp
        self.settings = dict(DEFAULT_DAQP_SETTINGS)
        self.settings.update(settings or {})
        unknown = sorted(set(self.settings) - set(daqp.Model().settings))
        if unknown:
            raise ParameterError(
                f"solver_settings: DAQP has no setting {unknown}; it knows "
                f"{sorted(daqp.Model().settings)}"
            )
        self.least_distance = bool(least_distance)
        self._models: dict = {}
        self._ldp: dict = {}

    def reset(self) -> None:
        """Forget every level's workspace."""
        self._models.clear()
        self._ldp.clear()

    def solve(self, key: object, qp: DenseQP) -> Solution:
        """Solve level ``key``'s QP with DAQP (warm start: its previous active set)."""
        start = time.perf_counter()
        if not (qp.lower <= qp.upper).all():
            bad = np.flatnonzero(~(qp.lower <= qp.upper))[:5].tolist()
            return Solution(False, f"invalid_bounds: lower > upper or NaN in rows {bad}")
        if self.least_distance and _sparse_rows(qp):
            buffers = self._least_distance(key, qp)
            if buffers is not None:
                return self._solve_ldp(key, buffers, start)
        return self._solve_as_is(key, qp, start)

    def _solve_as_is(self, key: object, qp: DenseQP, start: float) -> Solution:
        nv = qp.c.size
        # DAQP takes writable C-ordered buffers (the problem's rows may be read-only)
        h = np.require(qp.P, requirements=("C", "W"))
        f = np.require(qp.c, requirements=("C", "W"))
        a = np.require(qp.A[nv:], requirements=("C", "W"))
        lo = np.clip(qp.lower, -_BIG, _BIG)
        up = np.clip(qp.upper, -_BIG, _BIG)
        shape = a.shape
        entry = self._models.get(key)
        try:
            if entry is None or entry[1] != shape:
                model = self._daqp.Model()
                sense = np.zeros(lo.size, dtype=c_int)
                if model.setup(h, f, a, up, lo, sense)[0] < 0:
                    return Solution(False, "error: DAQP setup failed", 0, _since(start))
                model.settings = dict(self.settings)
            else:
                model = entry[0]
                # DAQP's update cannot take an A without rows (only bounds): leave it out
                rows = {"A": a} if a.shape[0] else {}
                if model.update(H=h, f=f, bupper=up, blower=lo, **rows) < 0:
                    self._models.pop(key, None)
                    return Solution(False, "error: DAQP refused the update", 0, _since(start))
            # DAQP keeps pointers to the arrays it was given: keep them alive with the model
            self._models[key] = (model, shape, (h, f, a, up, lo))
            x, _fval, flag, info = model.solve()
        except Exception as exc:  # noqa: BLE001 - a solver failure must not stop the loop
            self._models.pop(key, None)
            return Solution(False, f"error: {exc}", 0, _since(start))
        return self._answer(self._models, key, x, flag, info, start)

    def _least_distance(self, key: object, qp: DenseQP) -> dict | None:
        """The least-distance form of ``qp`` in this key's buffers, or ``None`` when ``P``
        is not safely positive definite."""
        nv = qp.c.size
        rows = qp.A.shape[0]
        entry = self._ldp.get(key)
        if entry is None or entry["m"].shape != (rows, nv):
            entry = {
                "m": np.empty((rows, nv)), "lo": np.empty(rows), "up": np.empty(rows),
                "linv_t": np.empty((1, nv, nv)), "w": np.empty(nv), "model": None,
            }  # fmt: skip
            self._ldp[key] = entry
        general = np.ascontiguousarray(qp.A[nv:])
        ok = dense_ldp(
            np.ascontiguousarray(qp.P), np.ascontiguousarray(qp.c), qp.lower, qp.upper,
            general, entry["m"], entry["lo"], entry["up"], entry["linv_t"], entry["w"],
        )  # fmt: skip
        return entry if ok else None

    def _solve_ldp(self, key: object, entry: dict, start: float) -> Solution:
        """DAQP on the least-distance problem in ``entry`` (``H = I`` for the workspace's
        life: later steps update ``M`` and the bounds only)."""
        model = entry["model"]
        try:
            if model is None:
                nv = entry["w"].size
                model = self._daqp.Model()
                sense = np.zeros(entry["lo"].size, dtype=c_int)
                eye, zero = np.eye(nv), np.zeros(nv)
                if model.setup(eye, zero, entry["m"], entry["up"], entry["lo"], sense)[0] < 0:
                    return Solution(False, "error: DAQP setup failed", 0, _since(start))
                model.settings = dict(self.settings)
                entry["model"], entry["kept"] = model, (eye, zero, sense)
            elif model.update(A=entry["m"], bupper=entry["up"], blower=entry["lo"]) < 0:
                self._ldp.pop(key, None)
                return Solution(False, "error: DAQP refused the update", 0, _since(start))
            u, _fval, flag, info = model.solve()
        except Exception as exc:  # noqa: BLE001 - a solver failure must not stop the loop
            self._ldp.pop(key, None)
            return Solution(False, f"error: {exc}", 0, _since(start))
        if u is not None and flag in (1, 2):
            u = ldp_solution(entry["linv_t"], np.asarray(u), entry["w"])
        return self._answer(self._ldp, key, u, flag, info, start)

    @staticmethod
    def _answer(store: dict, key: object, x, flag: int, info, start: float) -> Solution:
        """The :class:`Solution` of DAQP's answer; a failed workspace is forgotten."""
        iterations = int(info.get("iterations", 0)) if isinstance(info, dict) else 0
        ok = flag in (1, 2) and x is not None and bool(np.isfinite(x).all())
        if not ok:
            store.pop(key, None)
            status = _EXIT.get(int(flag), f"daqp_exit_{flag}")
            return Solution(False, status, iterations, _since(start))
        duals = np.asarray(info.get("lam")) if isinstance(info, dict) and "lam" in info else None
        return Solution(True, "solved", iterations, _since(start), np.array(x), duals)


def _sparse_rows(qp: DenseQP) -> bool:
    """Whether the general rows of ``qp`` are sparse enough for the least-distance form."""
    general = qp.A[qp.c.size :]
    return bool(np.count_nonzero(general) <= SPARSE_ROWS_SHARE * general.size)


def _since(start: float) -> float:
    return time.perf_counter() - start
