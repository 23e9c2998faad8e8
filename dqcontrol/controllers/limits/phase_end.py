"""The phase stays within the task: ``σ_p ≤ T_tot + T`` (docs/theory.md §8.4).

Past ``T_tot`` the target is held (zero derivative), so a plan whose phase ran beyond it
would promise progress that moves nothing; the row keeps the plan's phase on the path. The
one period of slack lets the first interval reach ``T_tot`` (with ``σ_p ≤ T_tot`` exactly,
the phase would only approach the end geometrically).
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Inequality
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.linalg.gram import frozen

__all__ = ["PhaseEndLimit"]


class PhaseEndLimit(Limit):
    """``σ + Σ_j Δ_j s_j ≤ T_tot + T`` (one row)."""

    name = "phase_end"

    def __init__(self, layout: DecisionLayout) -> None:
        c = np.zeros((1, layout.num_vars))
        c[0, layout.s_index()] = layout.durations_s
        self._c = frozen(c)
        self._lower = frozen(np.array([-np.inf]))

    def rows(self, ctx: StepContext) -> Inequality:
        """The row that bounds the phase's advance by what is left of ``T_tot``, plus ``T``."""
        room = max(ctx.trajectory.duration - ctx.sigma, 0.0) + ctx.period_s
        return Inequality(self.name, self._c, self._lower, np.array([room]))
