"""Stall damping: ``‖qd_i‖²`` weighted while the task is stalled (docs/theory.md §4.3).

When the path leaves the workspace, the time scaling drives ``s`` to 0; with ``s ≈ 0`` the
tracking term still asks ``J qd ≈ 0`` of a target the arm cannot reach, and near the
workspace's singular boundary the tiny regularisation lets the QP answer with large,
alternating joint speeds. Once the applied ``s`` has stayed below ``s_stall`` for a delay,
every block's cost gets

    μ_stall (1 - s / s_stall) ‖qd_i‖²        (s: the last applied scaling)

and the arm comes to rest near the path. The delay tells a stall from a slow start (at
1 kHz the arm needs many periods to accelerate, and ``s`` starts low). Otherwise the
weight is 0 and the cost is the thesis's.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Residual
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.term import Term

__all__ = ["StallDampingTerm"]


class StallDampingTerm(Term):
    """Rows ``qd_i`` with a weight that the term's memory of the applied ``s`` sets.

    Args:
        layout: the decision layout.
        weight_max: ``μ_stall`` (same unit as the tracking weight, ≥ 0; 0: never acts).
        stall_scaling: ``s_stall`` in ``(0, 1]``.
        delay_steps: how many consecutive steps ``s`` must stay below ``s_stall`` before
            the damping acts (≥ 0).

    :attr:`weight` is this step's weight, set by the memory: :meth:`observe` updates it
    after each step (and the weight of the next step with it).
    """

    name = "stall_damping"

    def __init__(
        self, layout: DecisionLayout, weight_max: float, stall_scaling: float, delay_steps: int
    ) -> None:
        self.weight_max = float(weight_max)
        self.stall_scaling = float(stall_scaling)
        self.delay_steps = int(delay_steps)
        p, n, m = layout.num_blocks, layout.num_joints, layout.block_size
        self._blocks = np.zeros((p, n, m))
        self._blocks[:, np.arange(n), np.arange(n)] = 1.0
        frozen(self._blocks)
        self._b = frozen(np.zeros(p * n))
        self._diag = np.arange(n)
        self.reset()

    @staticmethod
    def delay_steps_for(delay_s: float, period_s: float) -> int:
        """Steps of ``period_s`` [s] that make up ``delay_s`` [s] (rounded up)."""
        return math.ceil(delay_s / period_s - 1e-9)

    @property
    def weight(self) -> float:  # type: ignore[override]  # computed from the stall state
        """``μ_stall (1 - s / s_stall)`` once ``s`` has stayed below ``s_stall`` for
        ``delay_steps`` steps, else 0."""
        if self.stalled_steps >= self.delay_steps and self.weight_max:
            return self.weight_max * (1.0 - self.s_applied / self.stall_scaling)
        return 0.0

    def reset(self) -> None:
        """Forget the stall (``s`` applied 1, no stalled step)."""
        self.s_applied = 1.0
        self.stalled_steps = 0  # consecutive steps with s below stall_scaling

    def residual(self, ctx: StepContext) -> Residual:
        """The rows ``qd_i`` of every block, with the present :attr:`weight`."""
        return Residual(self.name, self.weight, self._b, blocks=self._blocks, held=False)

    def add_gram(self, ctx: StepContext, hessian: np.ndarray) -> bool:
        """Add ``2 weight`` to the joint-speed diagonal of every block while stalled."""
        if self.stalled_steps >= self.delay_steps and self.weight_max:
            weight = self.weight
            if weight:
                d = self._diag
                hessian[:, d, d] += 2.0 * weight
        return True

    def observe(self, z: np.ndarray | None, s_applied: float) -> None:
        """Count the consecutive steps with ``s`` below ``stall_scaling``."""
        self.s_applied = s_applied
        if s_applied < self.stall_scaling:
            self.stalled_steps += 1
        else:
            self.stalled_steps = 0
