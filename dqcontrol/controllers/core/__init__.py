"""The composable QP core (docs/theory.md §7): the decision layout, the step context, the
problem built at each step (residuals, bounds, inequality rows, levels), building and
solving the priority levels, and the one-level block assembly."""

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.levels import LevelsResult, build_problem, solve_levels
from dqcontrol.controllers.core.problem import (
    BlockQP,
    Bounds,
    DecisionLayout,
    DenseQP,
    Inequality,
    Level,
    Problem,
    Residual,
    Solution,
    StateRows,
)

__all__ = [
    "BlockQP",
    "Bounds",
    "DecisionLayout",
    "DenseQP",
    "Inequality",
    "Level",
    "LevelsResult",
    "Problem",
    "Residual",
    "Solution",
    "StateRows",
    "StepContext",
    "build_problem",
    "solve_levels",
]
