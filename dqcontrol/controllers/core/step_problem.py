"""What a controller hands its backend at one step (docs/theory.md §7.5).

A :class:`StepProblem` is the step's levels of terms and its limits at one
:class:`~dqcontrol.controllers.core.context.StepContext`, in the form a backend solves:
:attr:`StepProblem.block_form` is the one-level block-diagonal QP that a controller of one
level assembles straight from its terms and limits (``None`` when there are several
levels, or the terms are not block diagonal); :meth:`StepProblem.problem` gives the
:class:`~dqcontrol.controllers.core.problem.Problem` of every level, built once when
asked. Both come from the same terms and limits and hold the same numbers
(tests/controllers/core/test_block_assembly.py); the bounds the applied command is clipped to, and
the joints whose hard bound won a conflict, are read from the block form where there is one.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.controllers.core.levels import build_problem
from dqcontrol.controllers.core.problem import Level, Problem

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.core.block_assembly import BlockAssembly
    from dqcontrol.controllers.core.context import StepContext
    from dqcontrol.controllers.limits.limit import Limit

__all__ = ["StepProblem"]


class StepProblem:
    """The levels and limits of one step at a context, in the form a backend solves.

    Args:
        ctx: the step context.
        levels: the priority levels, highest first.
        limits: the limits of this attempt (a remedy changes them).
        assembly: the block assembly of a one-level controller (``None``: several levels).
        relaxed: the assembly leaves the relaxable limits out (the same set as ``limits``).
        warm: the previous plan shifted, for a backend that starts from it.

    Attributes:
        block_form: the one-level block-diagonal QP, built with the problem (``None`` where
            there are several levels or the terms are not block diagonal).
        block_diagonal: whether the terms are block diagonal (False once the assembly found
            them not to be, or with several levels).
        lower, upper: the bounds of the form built (the block form where there is one):
            the variables', then the rows'.
        has_conflict: whether a hard bound of the applied command won a conflict there.
    """

    __slots__ = (
        "_problem", "assembly", "block_diagonal", "block_form", "ctx", "has_conflict",
        "levels", "limits", "lower", "upper",
    )  # fmt: skip

    def __init__(
        self,
        ctx: StepContext,
        levels: tuple[Level, ...],
        limits: tuple[Limit, ...],
        assembly: BlockAssembly | None = None,
        relaxed: bool = False,
        warm: np.ndarray | None = None,
    ) -> None:
        self.ctx = ctx
        self.levels = levels
        self.limits = limits
        self.assembly = assembly
        self._problem: Problem | None = None
        blocks = None if assembly is None else assembly.build(ctx, relaxed, warm)
        self.block_form = blocks
        if blocks is None:
            self.block_diagonal = False
            self.lower: np.ndarray | None = None
            self.upper: np.ndarray | None = None
            self.has_conflict = False
        else:
            self.block_diagonal = True
            self.lower, self.upper = blocks.lower, blocks.upper
            self.has_conflict = assembly.has_conflict  # type: ignore[union-attr]

    def problem(self) -> Problem:
        """Every level's terms and every limit's rows (built once)."""
        problem = self._problem
        if problem is None:
            problem = self._problem = build_problem(self.ctx, self.levels, self.limits)
            if self.block_form is None:
                self.lower, self.upper = problem.lower, problem.upper
                n = self.ctx.layout.num_joints
                self.has_conflict = bool(problem.conflict[:n].any())
        return problem

    def conflict_joints(self, n: int) -> tuple[int, ...]:
        """The joints (of the applied command, the first ``n`` variables) whose hard bound
        won a conflict in the form built."""
        if self.block_form is not None:
            assembly = self.assembly
            assert assembly is not None, "a block form comes from the assembly"
            if not assembly.has_conflict:
                return ()
            mask = assembly.conflict[:n]
        else:
            mask = self.problem().conflict[:n]
            if not mask.any():
                return ()
        return tuple(np.flatnonzero(mask).tolist())
