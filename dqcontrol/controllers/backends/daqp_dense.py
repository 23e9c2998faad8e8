"""DAQP on dense QPs: one workspace per problem (priority level), updated in place each
step (docs/theory.md §7.5)."""

from __future__ import annotations

import time
from ctypes import c_int

import numpy as np

from dqcontrol.controllers.problem import DenseQP, Solution
from dqcontrol.errors import ParameterError

__all__ = ["DaqpBackend"]

#: DAQP settings of this backend: tighter primal tolerance than DAQP's 1e-6, so that the
#: rows holding a higher level (a band of ± its tolerance) are met to within 1e-9.
DEFAULT_DAQP_SETTINGS = {"primal_tol": 1e-9}

_EXIT = {-1: "primal_infeasible", -2: "cycling", -3: "unbounded", -4: "iteration_limit",
         -5: "nonconvex", -6: "initial_active_set_infeasible"}  # fmt: skip
_BIG = 1e30


class DaqpBackend:
    """Dense DAQP (dual active set), warm-started from the previous active set per key."""

    name = "daqp"

    def __init__(self, settings: dict | None = None) -> None:
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
        self._models: dict = {}

    def reset(self) -> None:
        """Forget every level's workspace."""
        self._models.clear()

    def solve(self, key: object, qp: DenseQP) -> Solution:
        """Solve level ``key``'s QP with DAQP (warm start: its previous active set)."""
        start = time.perf_counter()
        if not (qp.lower <= qp.upper).all():
            bad = np.flatnonzero(~(qp.lower <= qp.upper))[:5].tolist()
            return Solution(False, f"invalid_bounds: lower > upper or NaN in rows {bad}")
        nv = qp.c.size
        h = np.ascontiguousarray(qp.P)
        f = np.ascontiguousarray(qp.c)
        a = np.ascontiguousarray(qp.A[nv:])
        lo = np.clip(qp.lower, -_BIG, _BIG)
        up = np.clip(qp.upper, -_BIG, _BIG)
        entry = self._models.get(key)
        try:
            if entry is None or entry[1] != a.shape:
                model = self._daqp.Model()
                sense = np.zeros(lo.size, dtype=c_int)
                if model.setup(h, f, a, up, lo, sense)[0] < 0:
                    return Solution(False, "error: DAQP setup failed", 0, _since(start))
                model.settings = dict(self.settings)
                self._models[key] = (model, a.shape, (h, f, a, up, lo))
            else:
                model = entry[0]
                # DAQP's update cannot take an A without rows (only bounds): leave it out
                rows = {"A": a} if a.shape[0] else {}
                if model.update(H=h, f=f, bupper=up, blower=lo, **rows) < 0:
                    self._models.pop(key, None)
                    return Solution(False, "error: DAQP refused the update", 0, _since(start))
                self._models[key] = (model, a.shape, (h, f, a, up, lo))
            x, _fval, flag, info = model.solve()
        except Exception as exc:  # noqa: BLE001 - a solver failure must not stop the loop
            self._models.pop(key, None)
            return Solution(False, f"error: {exc}", 0, _since(start))
        iterations = int(info.get("iterations", 0)) if isinstance(info, dict) else 0
        ok = flag in (1, 2) and x is not None and bool(np.isfinite(x).all())
        if not ok:
            self._models.pop(key, None)
            status = _EXIT.get(int(flag), f"daqp_exit_{flag}")
            return Solution(False, status, iterations, _since(start))
        duals = np.asarray(info.get("lam")) if isinstance(info, dict) and "lam" in info else None
        return Solution(True, "solved", iterations, _since(start), np.array(x), duals)


def _since(start: float) -> float:
    return time.perf_counter() - start
