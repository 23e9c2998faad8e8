"""The range of the time scaling: ``s_min ≤ s_i ≤ s_max`` (docs/theory.md §3).

``s_i ≥ 0`` keeps the phase from ever decreasing; ``s_max`` is 1, or slightly above to let
a late task catch up; ``s_min = s_max = 1`` is the method without scaling.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import Bounds, DecisionLayout
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.linalg.gram import frozen

__all__ = ["ScalingRange"]


class ScalingRange(Limit):
    """``s_min ≤ s_i ≤ s_max`` for every block; with ``s_min == s_max`` an equality by
    design (``fixed``: a backend keeps it fixed for the life of its workspace)."""

    name = "scaling_range"

    def __init__(self, layout: DecisionLayout, s_min: float = 0.0, s_max: float = 1.0) -> None:
        p = layout.num_blocks
        self._rows = Bounds(
            self.name, frozen(layout.s_index()), frozen(np.full(p, s_min)),
            frozen(np.full(p, s_max)), fixed=s_min == s_max,
        )  # fmt: skip

    def rows(self, ctx: StepContext) -> Bounds:
        """The bounds ``s_min ≤ s_i ≤ s_max`` of every block: one constant object, built
        with the limit."""
        return self._rows
