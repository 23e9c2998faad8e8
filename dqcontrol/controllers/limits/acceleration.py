"""Joint acceleration: the applied command against the last one, and each block against
the previous block (docs/theory.md §4.2, §5).

- ``|qd_0 - qd_applied| ≤ T a_max,0``: a *hard* bound (it wins a conflict with the
  position and velocity bounds: the joint then brakes as hard as it allows);
- ``|qd_i - qd_{i-1}| ≤ h_i a_max,i`` for ``i ≥ 1`` (coupling rows), with ``h_i`` the time
  between the two blocks' commands: ``τ_i - τ_{i-1}`` for the thesis's instants,
  ``½ (Δ_i + Δ_{i-1})`` for intervals.

``a_max`` comes from the step context (constant, or dynamics-aware at each block's state).
``coupling_fraction < 1`` tightens the coupling rows (constraint tightening): the plan
beyond the applied command keeps that share of the acceleration in reserve, which absorbs
the error of a linearised prediction when the plan is revised.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.core.box_rules import hard_interval_into
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import Bounds, DecisionLayout, Inequality
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.linalg.gram import frozen

__all__ = ["AccelerationLimit"]


class AccelerationLimit(Limit):
    """The acceleration bound of the first block and the coupling between blocks.

    Args:
        layout: the decision layout.
        period_s: control period ``T`` [s].
        coupling_s: ``h_i`` for ``i = 1 … p-1`` [s] (empty for one block).
        coupling_fraction: share of ``a_max`` the coupling rows allow (``(0, 1]``).

    The first block's bound uses the step's period (``ctx.period_s``). Fast paths: the
    hard bound merged in one compiled call, and the coupling rows' bounds, both computed
    once for as long as ``ctx.a_max`` is the same array (a constant ``a_max``).
    """

    name = "acceleration"
    hard = True

    def __init__(
        self,
        layout: DecisionLayout,
        period_s: float,
        coupling_s: np.ndarray,
        coupling_fraction: float = 1.0,
    ) -> None:
        self.period_s = float(period_s)
        self.coupling_s = np.asarray(coupling_s, dtype=float) * float(coupling_fraction)
        p, n = layout.num_blocks, layout.num_joints
        idx = layout.qd_index()
        self._first = idx[0]
        c = np.zeros(((p - 1) * n, layout.num_vars))
        rows = np.arange((p - 1) * n)
        c[rows, idx[1:].ravel()] = 1.0
        c[rows, idx[:-1].ravel()] = -1.0
        self._c = frozen(c)
        self._step_key: tuple = (None, None)
        self._step0 = np.zeros(n)
        self._dv_key: object = None
        self._dv = np.zeros(0)
        self._neg_dv = np.zeros(0)

    def _first_step(self, ctx: StepContext) -> np.ndarray:
        """``T a_max,0`` [rad/s], cached while ``ctx.a_max`` and ``T`` stay the same."""
        a_max, period = ctx.a_max, ctx.period_s
        key = self._step_key
        if a_max is not key[0] or period != key[1]:
            self._step0 = period * a_max[0]
            self._step_key = (a_max, period)
        return self._step0

    def _coupling(self, ctx: StepContext) -> np.ndarray:
        """``h_i a_max,i`` of every coupling row, cached while ``ctx.a_max`` is the same."""
        if ctx.a_max is not self._dv_key:
            dv, neg_dv = coupling_steps(self.coupling_s, ctx.a_max)
            self._dv, self._neg_dv = frozen(dv), frozen(neg_dv)
            self._dv_key = ctx.a_max
        return self._dv

    def tighten(self, ctx, lower, upper, conflict) -> bool:
        """Intersect the first block's acceleration interval into ``lower``/``upper``."""
        key = self._step_key
        step0 = self._step0
        if ctx.a_max is not key[0] or ctx.period_s != key[1]:
            step0 = self._first_step(ctx)
        hard_interval_into(lower, upper, conflict, self._first, ctx.qd_prev, step0)
        return True

    def row_bounds(self, ctx, lower, upper) -> bool:
        """Write the coupling rows' bounds ``±h_i a_max,i`` to ``lower``/``upper``."""
        dv = self._coupling(ctx)
        np.negative(dv, out=lower)
        upper[:] = dv
        return True

    def rows(self, ctx: StepContext) -> tuple:
        """The first block's bounds and the coupling rows between consecutive blocks."""
        step0 = self._first_step(ctx)
        first = Bounds(
            "acceleration_first",
            self._first,
            ctx.qd_prev - step0,
            ctx.qd_prev + step0,
            hard=True,
        )
        if self._c.shape[0] == 0:
            return (first,)
        dv = self._coupling(ctx)
        return first, Inequality("acceleration_coupling", self._c, self._neg_dv, dv)


@compiled
def coupling_steps(coupling_s: np.ndarray, a_max: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``h_i a_max[i + 1]`` of every coupling row, flat ``((p - 1) n,)``, and its negation."""
    rows, n = coupling_s.shape[0], a_max.shape[1]
    dv, neg_dv = np.empty(rows * n), np.empty(rows * n)
    for i in range(rows):
        for j in range(n):
            v = coupling_s[i] * a_max[i + 1, j]
            dv[i * n + j] = v
            neg_dv[i * n + j] = -v
    return dv, neg_dv
