"""Joint velocity bounds on every block: ``-qd_max ≤ qd_i ≤ qd_max`` (docs/theory.md §5)."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import Bounds, DecisionLayout
from dqcontrol.controllers.limits.limit import Limit

__all__ = ["VelocityLimit"]


class VelocityLimit(Limit):
    """``|qd_i| ≤ qd_max`` [rad/s] for every block ``i``."""

    name = "velocity"

    def __init__(self, layout: DecisionLayout, qd_max: np.ndarray) -> None:
        p = layout.num_blocks
        self._rows = Bounds(
            self.name,
            layout.qd_index().ravel(),
            np.tile(-np.asarray(qd_max, dtype=float), p),
            np.tile(np.asarray(qd_max, dtype=float), p),
        )

    def rows(self, ctx: StepContext) -> Bounds:
        """The velocity bounds ``±qd_max`` of every block."""
        return self._rows
