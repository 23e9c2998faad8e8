"""Posture: joint velocities towards a preferred configuration (docs/theory.md §7.3).

Rows ``qd_i - K_p (q_ref - q̄_i)`` for every block (``q̄_i`` the block's linearisation
state): a first-order pull of each joint towards ``q_ref`` at rate ``K_p``. Below a
higher-priority task it acts in that task's null space (the redundancy), so a redundant
arm does not drift.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.base import check_positive
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Residual
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.term import Term

__all__ = ["PostureTerm"]


class PostureTerm(Term):
    """Pull towards ``reference`` (a configuration [rad]; set by the controller at reset).

    ``ctx.posture_scale`` (default 1) scales the gain: a controller sets it to 0
    to hold the arm still (the rows then ask for ``qd_i = 0``).

    Args:
        layout: the decision layout.
        gain_per_s: ``K_p`` [1/s].
        weight: weight of the term.
    """

    name = "posture"

    def __init__(self, layout: DecisionLayout, gain_per_s: float = 1.0, weight: float = 1.0):
        self.weight = float(weight)
        self.gain_per_s = check_positive("posture gain_per_s", gain_per_s, "1/s")
        p, n, m = layout.num_blocks, layout.num_joints, layout.block_size
        self._blocks = np.zeros((p, n, m))
        self._blocks[:, np.arange(n), np.arange(n)] = 1.0
        frozen(self._blocks)
        self.reference: np.ndarray | None = None

    def residual(self, ctx: StepContext) -> Residual:
        """The rows that pull the predicted states towards the posture."""
        ref = ctx.q if self.reference is None else self.reference
        gain = self.gain_per_s * float(ctx.posture_scale)
        q_lin = ctx.prediction.q_lin
        b = np.empty(q_lin.size)
        pull_into(ref, q_lin, gain, b)
        return Residual(self.name, self.weight, b, blocks=self._blocks)


@compiled
def pull_into(reference: np.ndarray, states: np.ndarray, gain: float, out: np.ndarray) -> None:
    """``out = (gain (reference - states)).ravel()`` for states ``(p, n)``, entry by entry."""
    n = states.shape[1]
    for i in range(states.shape[0]):
        for k in range(n):
            out[i * n + k] = gain * (reference[k] - states[i, k])
