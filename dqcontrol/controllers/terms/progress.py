"""Progress along the task: each interval's time scaling towards its reference
(docs/theory.md §8.3).

Rows ``sqrt(c_i) (s_ref - s_i)`` with ``c_i = Δ_i (p - i) / τ_p``: the phase at the end of
the horizon weights ``s_i`` by how many predicted states it advances
(``Σ_k σ_k = const + Σ_i Δ_i (p - i) s_i``), so the earliest intervals matter most. The
reference is 1 (nominal speed), or, with catch-up (``s_max > 1``), ``1 + lag / τ_p``
clipped to ``s_max``, where ``lag = t - σ`` is how far the task is behind its nominal
timing.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Residual
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.term import Term

__all__ = ["ProgressTerm"]


class ProgressTerm(Term):
    """Progress rows on ``s``; ``ctx.lag_s`` (``t - σ`` [s]) drives catch-up.

    Args:
        layout: the decision layout (intervals).
        s_max: largest time scaling (1: no catch-up).
        weight: weight of the term.
    """

    name = "progress"

    def __init__(self, layout: DecisionLayout, s_max: float = 1.0, weight: float = 1.0) -> None:
        self.weight = float(weight)
        self.s_max = float(s_max)
        p = layout.num_blocks
        durations = layout.durations_s
        horizon = float(durations.sum())
        self._scale = np.sqrt(durations * (p - np.arange(p)) / horizon)
        self._blocks = np.zeros((p, 1, layout.block_size))
        self._blocks[:, 0, layout.num_joints] = -self._scale
        self._horizon = horizon
        frozen(self._blocks)
        self._nominal_b = frozen(-self._scale * 1.0)  # b at s_ref = 1

    def reference(self, lag_s: float) -> float:
        """``s_ref``: 1, or up to ``s_max`` to recover a lag of ``lag_s`` [s]."""
        if self.s_max <= 1.0:
            return 1.0
        return float(min(self.s_max, 1.0 + max(lag_s, 0.0) / self._horizon))

    def residual(self, ctx: StepContext) -> Residual:
        """The rows that pull the predicted phase towards the reference timing."""
        s_ref = self.reference(float(ctx.lag_s))
        b = self._nominal_b if s_ref == 1.0 else -self._scale * s_ref
        return Residual(self.name, self.weight, b, blocks=self._blocks)
