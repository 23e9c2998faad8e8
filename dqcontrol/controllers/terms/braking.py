"""The progress level's goal during a stop: every interval's time scaling towards 0
(docs/theory.md §8.10).

The rows of :class:`~dqcontrol.controllers.terms.progress.ProgressTerm` with the reference
0 instead of 1: ``sqrt(c_i) (0 - s_i)``, the earliest intervals weighted most, so the phase
is braked as fast as the limits and the path level (held above) allow.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Residual
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.progress import ProgressTerm

__all__ = ["BrakingTerm"]


class BrakingTerm(ProgressTerm):
    """Progress rows with the reference ``s = 0``."""

    name = "braking"

    def __init__(self, layout: DecisionLayout, weight: float = 1.0) -> None:
        super().__init__(layout, 1.0, weight)
        self._zero_b = frozen(np.zeros(layout.num_blocks))

    def residual(self, ctx: StepContext) -> Residual:
        """The rows that pull every interval's scaling to 0."""
        return Residual(self.name, self.weight, self._zero_b, blocks=self._blocks)
