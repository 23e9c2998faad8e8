"""Joint acceleration: the applied command against the last one, and each block against
the previous block (FORMULATION §6, §5.3, §10).

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

from dqcontrol.controllers.context import StepContext
from dqcontrol.controllers.problem import Bounds, DecisionLayout, Inequality, Limit

__all__ = ["AccelerationLimit"]


class AccelerationLimit(Limit):
    """The acceleration bound of the first block and the coupling between blocks.

    Args:
        layout: the decision layout.
        period_s: control period ``T`` [s].
        coupling_s: ``h_i`` for ``i = 1 … p-1`` [s] (empty for one block).
        coupling_fraction: share of ``a_max`` the coupling rows allow (``(0, 1]``).
    """

    name = "acceleration"

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
        self._c = c

    def rows(self, ctx: StepContext) -> tuple:
        step0 = self.period_s * ctx.a_max[0]
        first = Bounds(
            "acceleration_first",
            self._first,
            ctx.qd_prev - step0,
            ctx.qd_prev + step0,
            hard=True,
        )
        if self._c.shape[0] == 0:
            return (first,)
        dv = (self.coupling_s[:, None] * ctx.a_max[1:]).ravel()
        return first, Inequality("acceleration_coupling", self._c, -dv, dv)
