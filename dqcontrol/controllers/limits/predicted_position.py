"""Joint positions at every predicted state, and a terminal braking condition
(docs/theory.md §8.4).

With states affine in the decision (``q_i = q_base_i + Σ_j W_ij qd_j``), the position
bounds are exact linear rows ``q_min ≤ q_i ≤ q_max`` at every breakpoint. At the last
state the arm must also be able to stop inside the limits from the last command: braking
from ``v`` at ``a`` covers ``v² / (2 a) ≤ |v| qd_max / (2 a)``, so

    q_min ≤ q_p + c qd_{p-1} ≤ q_max,     c = qd_max / (2 a_max)

is sufficient (linear and conservative), and keeps the next problem's braking plan
feasible.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.context import StepContext
from dqcontrol.controllers.problem import DecisionLayout, Inequality, Limit

__all__ = ["PredictedPositionLimit"]


class PredictedPositionLimit(Limit):
    """Position rows at every predicted state plus the terminal braking rows.

    Args:
        layout: the decision layout.
        q_min, q_max: position bounds [rad] (already shrunk by any margin).
        qd_max: velocity bound [rad/s] (for the braking coefficient).
        terminal: add the terminal braking rows.
    """

    name = "predicted_position"

    def __init__(
        self,
        layout: DecisionLayout,
        q_min: np.ndarray,
        q_max: np.ndarray,
        qd_max: np.ndarray,
        *,
        terminal: bool = True,
    ) -> None:
        self.layout = layout
        self.q_min = np.asarray(q_min, dtype=float)
        self.q_max = np.asarray(q_max, dtype=float)
        self.qd_max = np.asarray(qd_max, dtype=float)
        self.terminal = bool(terminal)
        self._weights: np.ndarray | None = None
        self._c: np.ndarray | None = None

    def _matrix(self, weights: np.ndarray) -> np.ndarray:
        """Rows ``q_i = Σ_j W_ij qd_j`` as a ``(p n, len(z))`` matrix (cached per ``W``)."""
        if self._weights is not weights:
            layout = self.layout
            p, n = layout.num_blocks, layout.num_joints
            c = np.zeros((p * n, layout.num_vars))
            idx = layout.qd_index()
            for i in range(p):
                for j in range(i + 1):
                    c[i * n + np.arange(n), idx[j]] = weights[i, j]
            self._weights, self._c = weights, c
        return self._c

    def rows(self, ctx: StepContext) -> tuple:
        pred = ctx.prediction
        c = self._matrix(pred.weights)
        base = pred.q_base.ravel()
        p = self.layout.num_blocks
        out = [
            Inequality(
                self.name,
                c,
                np.tile(self.q_min, p) - base,
                np.tile(self.q_max, p) - base,
            )
        ]
        if self.terminal:
            n = self.layout.num_joints
            coeff = self.qd_max / (2.0 * ctx.a_max[-1])
            last = c[-n:].copy()
            last[np.arange(n), self.layout.qd_index()[-1]] += coeff
            out.append(
                Inequality(
                    "terminal_braking",
                    last,
                    self.q_min - pred.q_base[-1],
                    self.q_max - pred.q_base[-1],
                )
            )
        return tuple(out)
