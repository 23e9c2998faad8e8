"""Progress at full speed: ``1 - s_i`` at every block (docs/theory.md §4.2, thesis eq. 3.7).

Weighted ``λ2 ≪ λ1`` below the tracking term, it makes ``s`` as large as the limits let the
task be tracked; at a separate, lower priority level it is the strict form of the same
preference.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Residual
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.term import Term

__all__ = ["ScalingTerm"]


class ScalingTerm(Term):
    """``λ2 Σ_i (1 - s_i)²``: rows ``s_i - 1``.

    Args:
        layout: the decision layout (with time scaling).
        weight: ``λ2`` (dimensionless, ≥ 0).
    """

    name = "scaling"

    def __init__(self, layout: DecisionLayout, weight: float) -> None:
        self.weight = float(weight)
        p, m = layout.num_blocks, layout.block_size
        layout.s_index()  # a layout without s is refused here
        blocks = np.zeros((p, 1, m))
        blocks[:, 0, layout.num_joints] = 1.0
        self._rows = Residual(self.name, self.weight, frozen(np.ones(p)), blocks=frozen(blocks))

    def residual(self, ctx: StepContext) -> Residual:
        """The rows ``s_i - 1`` of every block: one constant residual, built with the term."""
        return self._rows
