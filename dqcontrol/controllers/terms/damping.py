"""Damping ``μ ‖qd_i‖²`` (and optionally ``μ ‖s_i‖²``): the small regularisation that makes
a level's cost strictly convex (docs/theory.md §4.2)."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Residual
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.term import Term

__all__ = ["DampingTerm"]


class DampingTerm(Term):
    """Rows ``qd_i`` (and ``s_i`` with ``include_scaling``), weight ``μ``.

    Args:
        layout: the decision layout.
        weight: ``μ``.
        include_scaling: damp ``s_i`` too.
        held: whether lower levels hold these rows (a regularisation is not held).
    """

    name = "damping"

    def __init__(
        self,
        layout: DecisionLayout,
        weight: float,
        *,
        include_scaling: bool = False,
        held: bool = False,
    ) -> None:
        self.weight = float(weight)
        self.held = bool(held)
        p, n, m = layout.num_blocks, layout.num_joints, layout.block_size
        k = m if (include_scaling and layout.with_scaling) else n
        blocks = np.zeros((p, k, m))
        blocks[:, np.arange(k), np.arange(k)] = 1.0
        b = np.zeros(p * k)
        self._rows = Residual(
            self.name, self.weight, frozen(b), blocks=frozen(blocks), held=self.held
        )

    def residual(self, ctx: StepContext) -> Residual:
        """The rows ``qd_i`` (and ``s_i`` with ``include_scaling``) of every block, ``b = 0``:
        one constant residual, built with the term."""
        return self._rows
