"""Building a step's problem and solving its priority levels (docs/theory.md §7.4).

Level ``k`` minimises its terms subject to the limits and to every higher level held at its
optimum: after level ``k`` is solved at ``z_k``, each of its held residual rows ``a`` is
kept at ``a · z_k`` by the lower levels, as an equality (a backend may eliminate these
rows and solve in their null space). For least squares this is exact: the optimal residual
of a convex level is unique, so the set of its minimisers is the set of feasible points
with that residual. Should a level with its held equalities fail (rounding can make an
equality that the level above met only to the solver's tolerance inconsistent with a
limit), it is solved again with each held row within ``±tolerance`` of its value
(two-sided rows) instead. One level with weights is the thesis's controllers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dqcontrol.controllers.backends.base import Backend
from dqcontrol.controllers.context import StepContext
from dqcontrol.controllers.problem import (
    Bounds,
    BuiltLevel,
    DenseQP,
    Inequality,
    Level,
    Limit,
    Problem,
    Solution,
    fixed_variables,
    merge_bounds,
    objective,
)

__all__ = [
    "LevelsResult",
    "build_problem",
    "held_rows",
    "level_qp",
    "residual_values",
    "solve_levels",
]


def _limit_rows(limits: tuple[Limit, ...], ctx: StepContext) -> tuple[list, list]:
    bounds: list[Bounds] = []
    general: list[Inequality] = []
    for limit in limits:
        out = limit.rows(ctx)
        if out is None:
            continue
        for item in (out,) if isinstance(out, Bounds | Inequality) else out:
            (bounds if isinstance(item, Bounds) else general).append(item)
    return bounds, general


def build_problem(
    ctx: StepContext,
    levels: tuple[Level, ...],
    limits: tuple[Limit, ...],
    cache: dict | None = None,
) -> Problem:
    """Evaluate every term and limit at ``ctx``; ``cache`` keeps constant terms' rows."""
    built = []
    for lev in levels:
        residuals = []
        for term in lev.terms:
            if term.constant and cache is not None:
                res = cache.get(id(term))
                if res is None:
                    res = cache[id(term)] = term.residual(ctx)
            else:
                res = term.residual(ctx)
            residuals.append(res)
        built.append(BuiltLevel(lev.name, lev.tolerance, tuple(residuals)))
    bounds, general = _limit_rows(limits, ctx)
    lower, upper, conflict = merge_bounds(ctx.layout, tuple(bounds))
    fixed = fixed_variables(ctx.layout, tuple(bounds))
    if general:
        lower = np.concatenate([lower] + [g.lower for g in general])
        upper = np.concatenate([upper] + [g.upper for g in general])
    return Problem(
        ctx.layout, tuple(built), tuple(bounds), tuple(general), lower, upper, conflict, fixed
    )


@dataclass(frozen=True)
class LevelsResult:
    """The lexicographic solve: the final point and each level's solution.

    ``solution`` is the lowest level solved; if a lower level fails, the last level that
    succeeded gives the point and ``failed_level`` names the one that failed.
    """

    solution: Solution
    per_level: tuple[Solution, ...]
    failed_level: int | None = None

    @property
    def iterations(self) -> int:
        """The solver iterations of every level solved, summed."""
        return sum(s.iterations for s in self.per_level)

    @property
    def solve_time_s(self) -> float:
        """The time [s] inside the solver for every level solved, summed."""
        return sum(s.solve_time_s for s in self.per_level)


def level_qp(problem: Problem, k: int, held: list[tuple], equalities: bool = False) -> DenseQP:
    """Level ``k``'s dense QP with the rows ``held`` (``(A, lower, upper)``) of the levels
    above it, marked as equalities if ``equalities`` (then ``lower == upper`` on them)."""
    p_mat, c = objective(problem.layout, problem.levels[k].residuals)
    count = sum(h[0].shape[0] for h in held) if equalities else 0
    return DenseQP(
        p_mat,
        c,
        np.vstack([problem.A] + [h[0] for h in held]),
        np.concatenate([problem.lower] + [h[1] for h in held]),
        np.concatenate([problem.upper] + [h[2] for h in held]),
        count,
    )


#: Share of a level's tolerance given to the backend as the band of the held rows: the rest
#: absorbs the backend's own feasibility error (DAQP measures it in its scaled variables), so
#: that the stated tolerance holds in the rows' units.
HELD_BAND_SHARE = 0.5


def held_rows(problem: Problem, k: int, z: np.ndarray, exact: bool = False) -> tuple | None:
    """``(A, lower, upper)`` holding level ``k``'s held residuals at their values at ``z``
    (``exact``) or within the level's tolerance of them (the band given to the backend is
    :data:`HELD_BAND_SHARE` of it)."""
    layout = problem.layout
    level = problem.levels[k]
    mats = [r.dense(layout) for r in level.residuals if r.held]
    if not mats:
        return None
    a = np.vstack(mats)
    value = a @ z
    if exact:
        return a, value, value
    band = HELD_BAND_SHARE * level.tolerance
    return a, value - band, value + band


def solve_levels(problem: Problem, backend: Backend) -> LevelsResult:
    """Solve the levels in order, each holding the ones above (see the module docstring)."""
    points: list[np.ndarray] = []
    exact: list[tuple] = []
    per_level: list[Solution] = []
    best: Solution | None = None
    for k in range(len(problem.levels)):
        sol = _solve_level(problem, k, points, exact, backend)
        per_level.append(sol)
        if not sol.ok:
            if best is None:
                return LevelsResult(sol, tuple(per_level), 0)
            return LevelsResult(best, tuple(per_level), k)
        best = sol
        assert sol.x is not None, "a solved level has its solution"
        points.append(sol.x)
        if k + 1 < len(problem.levels):
            rows = held_rows(problem, k, sol.x, exact=True)
            if rows is not None:
                exact.append(rows)
    assert best is not None, "a problem has at least one level"
    return LevelsResult(best, tuple(per_level), None)


def _solve_level(
    problem: Problem, k: int, points: list[np.ndarray], exact: list[tuple], backend: Backend
) -> Solution:
    """Level ``k`` holding each level ``j < k`` at its solution ``points[j]``: exactly
    (the rows ``exact``) first, within the tolerances if that fails (backend key
    ``(k, "band")``)."""
    sol = backend.solve(k, level_qp(problem, k, exact, equalities=True))
    if sol.ok or not exact:
        return sol
    band = [held_rows(problem, j, z) for j, z in enumerate(points)]
    again = backend.solve((k, "band"), level_qp(problem, k, [r for r in band if r is not None]))
    return again if again.ok else sol


def residual_values(problem: Problem, z: np.ndarray) -> list[dict[str, float]]:
    """``{term name: ‖A z - b‖}`` per level (diagnostics and tests)."""
    out = []
    for lev in problem.levels:
        out.append(
            {r.name: float(np.linalg.norm(r.value(problem.layout, z))) for r in lev.residuals}
        )
    return out
