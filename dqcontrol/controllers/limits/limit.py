"""The contract of a limit (docs/theory.md §7.3): inequality rows, or nothing when inactive."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.controllers.core.problem import Bounds, Inequality

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.core.context import StepContext

__all__ = ["Limit"]


class Limit(ABC):
    """A constraint: rows, or nothing when inactive.

    Subclasses set ``name`` and implement :meth:`rows`, returning :class:`Bounds`,
    :class:`Inequality`, a tuple of them, or ``None``.

    Class attributes: ``hard`` (its :class:`Bounds` are hard: merged after every soft
    bound, with the conflict rule), ``relaxable`` (dropped when the problem is infeasible,
    to regain feasibility). A limit whose rows never change builds them once from
    read-only arrays and returns that object at every call: it is then evaluated once
    (:func:`~dqcontrol.controllers.core.problem.constant_rows`).

    Optional fast paths: :meth:`tighten` (the :class:`Bounds` of this step merged into the
    variable bounds in place) and :meth:`row_bounds` (the bounds of its
    :class:`Inequality` rows, whose matrix ``C`` must then be the same at every step).
    """

    name: str = "limit"
    hard: bool = False
    relaxable: bool = False

    @abstractmethod
    def rows(self, ctx: StepContext) -> Bounds | Inequality | tuple | None:
        """This step's rows, or ``None`` when the limit is inactive."""

    def tighten(
        self, ctx: StepContext, lower: np.ndarray, upper: np.ndarray, conflict: np.ndarray
    ) -> bool:
        """Fast path: intersect this step's :class:`Bounds` into ``lower``/``upper``
        (the variables' entries, in place; hard ones with the conflict rule, marking
        ``conflict``) exactly as :func:`merge_bounds` would, and return True; False when
        not offered. A limit that offers it gives :class:`Inequality` rows only with the
        same matrix at every step (their bounds through :meth:`row_bounds`)."""
        return False

    def row_bounds(self, ctx: StepContext, lower: np.ndarray, upper: np.ndarray) -> bool:
        """Fast path: write the bounds of this step's :class:`Inequality` rows (in the
        order :meth:`rows` gives them) to ``lower``/``upper`` and return True; False when
        not offered."""
        return False
