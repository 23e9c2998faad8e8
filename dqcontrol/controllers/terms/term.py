"""The contract of a cost term (docs/theory.md §7.3): residual rows with a weight."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.controllers.core.problem import Residual

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.core.context import StepContext

__all__ = ["Term"]


class Term(ABC):
    """A cost term: residual rows with a weight.

    Subclasses set ``name`` and ``weight`` and implement :meth:`residual`. A term whose
    rows never change builds its :class:`Residual` once from read-only arrays
    (:func:`~dqcontrol.controllers.linalg.gram.frozen`) and returns that object at every
    call: it is then evaluated once
    (:func:`~dqcontrol.controllers.core.problem.constant_rows`).

    Optional hooks: :meth:`prepare` (start of every step, before any row is read: a term
    with memory fixes this step's values there), :meth:`observe` (after every step: the
    memory's update), :meth:`reset`, and the fast path :meth:`add_gram`.
    """

    name: str = "term"
    weight: float = 1.0

    @abstractmethod
    def residual(self, ctx: StepContext) -> Residual:
        """The rows ``A z - b`` of this step."""

    def prepare(self, ctx: StepContext) -> None:  # noqa: B027 - optional hook
        """Start of a step: fix what :meth:`residual` and :meth:`add_gram` will read."""

    def add_gram(self, ctx: StepContext, hessian: np.ndarray) -> bool:
        """Fast path of a term whose rows each touch one block and whose ``b`` is zero:
        add ``2 w Σ_i A_iᵀ A_i`` to the blocks ``hessian`` ``(p, m, m)`` in place (the
        Hessian of ``w ‖A z‖²``) and return True; False (the default) when not offered,
        and the caller then uses :meth:`residual`."""
        return False

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget any memory (called by the controller's reset)."""

    def observe(self, z: np.ndarray | None, s_applied: float) -> None:  # noqa: B027
        """Called after every step with the solution (``None`` on a fallback)."""
