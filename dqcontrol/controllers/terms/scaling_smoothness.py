"""Smoothness of the time scaling: ``s_0 - s_applied`` and ``s_i - s_{i-1}``
(docs/theory.md §8.3)."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Residual
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.term import Term

__all__ = ["ScalingSmoothnessTerm"]


class ScalingSmoothnessTerm(Term):
    """Rows ``s_0 - s_prev`` and ``s_i - s_{i-1}``; ``ctx.s_prev`` is the last
    applied scaling (0 before the first step).

    Args:
        layout: the decision layout.
        weight: weight of the term (small: it only shapes ``s`` where progress leaves
            freedom).
    """

    name = "scaling_smoothness"

    def __init__(self, layout: DecisionLayout, weight: float = 1e-2) -> None:
        self.weight = float(weight)
        p = layout.num_blocks
        idx = layout.s_index()
        a = np.zeros((p, layout.num_vars))
        a[np.arange(p), idx] = 1.0
        a[np.arange(1, p), idx[:-1]] = -1.0
        self._a = frozen(a)

    def residual(self, ctx: StepContext) -> Residual:
        """The rows ``s_i - s_(i-1)`` (``s_0``: the applied ``s``)."""
        b = np.zeros(self._a.shape[0])
        b[0] = float(ctx.s_prev)
        return Residual(self.name, self.weight, b, A=self._a)
