"""The applied command's own box: velocity, position through one period, and braking
(docs/theory.md §5), as soft bounds on ``qd_0``.

Merged with the hard acceleration bound of the first block (the conflict rule), this is
the thesis's command box: where a joint moves too fast towards its limit to stop in time,
the acceleration bound is kept and the joint brakes as hard as it allows.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.bounds import velocity_position_box
from dqcontrol.controllers.context import StepContext
from dqcontrol.controllers.problem import Bounds, DecisionLayout, Limit

__all__ = ["AppliedCommandBox"]


class AppliedCommandBox(Limit):
    """Soft bounds on ``qd_0`` from ``q``: ``|qd| ≤ qd_max``, ``q + T qd`` within the
    limits, and slow enough to stop before them at ``a_max``."""

    name = "applied_box"

    def __init__(
        self,
        layout: DecisionLayout,
        q_min: np.ndarray,
        q_max: np.ndarray,
        qd_max: np.ndarray,
        period_s: float,
    ) -> None:
        self._index = layout.qd_index()[0]
        self.q_min, self.q_max, self.qd_max = q_min, q_max, qd_max
        self.period_s = float(period_s)

    def rows(self, ctx: StepContext) -> Bounds:
        """The bounds of the applied command's block."""
        lo, up = velocity_position_box(
            ctx.q, self.q_min, self.q_max, self.qd_max, self.period_s, ctx.a_max[0]
        )
        return Bounds(self.name, self._index, lo, up)
