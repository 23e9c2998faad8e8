"""Building a step's problem and solving its priority levels (docs/theory.md §7.4).

Level ``k`` minimises its terms subject to the limits and to every higher level held at its
optimum: after level ``k`` is solved at ``z_k``, each of its held residual rows ``a`` is
kept at ``a · z_k`` by the lower levels. For least squares this is exact: the optimal
residual of a convex level is unique, so the set of its minimisers is the set of feasible
points with that residual. The held rows are kept by construction: level ``k + 1`` moves
only in their null space, ``z = z_k + Z_k y`` with ``Z_k`` an orthonormal basis of the
null space of every held row so far (:func:`~dqcontrol.controllers.linalg.null_space.null_space`,
each level narrowing the last basis), so its QP has ``dim Z_k`` variables instead of all.
Should that reduced level fail (rounding at a degenerate vertex can leave no ``y`` that
meets the limits to the solver's tolerance), it is solved again over all variables with
each held row within ``±tolerance`` of its value (two-sided rows) instead. A backend with
``solve_warm_levels`` may solve the first levels in one call on their last active sets
(docs/theory.md §7.5); the levels it leaves go on one by one. One level with weights is
the thesis's controllers.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from dqcontrol._blas import single_blas_thread
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.objective import (
    dense_hessian,
    level_objective,
    state_objective,
)
from dqcontrol.controllers.core.problem import (
    Bounds,
    BuiltLevel,
    DenseQP,
    Inequality,
    Level,
    Problem,
    Residual,
    Solution,
    SplitQP,
    WarmLevels,
    fixed_variables,
    merge_bounds,
    objective,
)
from dqcontrol.controllers.core.reduced import ReducedQP, level_rows
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.linalg.null_space import null_space

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.backends.base import Backend

__all__ = [
    "LevelsResult",
    "build_problem",
    "held_rows",
    "level_qp",
    "level_in_basis",
    "residual_values",
    "solve_levels",
]


def _limit_rows(limits: tuple[Limit, ...], ctx: StepContext) -> tuple[tuple, tuple]:
    bounds: list[Bounds] = []
    general: list[Inequality] = []
    for limit in limits:
        out = limit.rows(ctx)
        if out is None:
            continue
        if type(out) is not tuple:  # one item (a NamedTuple), or another iterable
            out = (out,) if isinstance(out, Bounds | Inequality) else tuple(out)
        for item in out:
            (bounds if isinstance(item, Bounds) else general).append(item)
    return tuple(bounds), tuple(general)


def build_problem(
    ctx: StepContext,
    levels: tuple[Level, ...],
    limits: tuple[Limit, ...],
) -> Problem:
    """Evaluate every term and limit at ``ctx`` (a term in several levels once)."""
    built = []
    now: dict[int, Residual] = {}  # this step's residuals, by term
    for lev in levels:
        residuals = []
        for term in lev.terms:
            res = now.get(id(term))
            if res is None:
                res = term.residual(ctx)
            now[id(term)] = res
            residuals.append(res)
        built.append(BuiltLevel(lev.name, lev.tolerance, tuple(residuals)))
    bounds, general = _limit_rows(limits, ctx)
    lower, upper, conflict = merge_bounds(ctx.layout, bounds)
    fixed = fixed_variables(ctx.layout, bounds)
    if general:
        lower = np.concatenate((lower, *[g.lower for g in general]))
        upper = np.concatenate((upper, *[g.upper for g in general]))
    return Problem(ctx.layout, tuple(built), bounds, general, lower, upper, conflict, fixed)


class LevelsResult(NamedTuple):
    """The lexicographic solve: the final point and each level's solution.

    ``solution`` is the lowest level solved; if a lower level fails, the last level that
    succeeded gives the point and ``failed_level`` names the one that failed. ``time_s``
    is the wall time of the whole solve [s]: every level's reduction to the null space of
    the rows held above and its backend solve; ``iterations`` and ``solve_time_s`` the
    solver's iterations and time [s] inside it for every level solved, summed.
    """

    solution: Solution
    per_level: tuple[Solution, ...]
    failed_level: int | None = None
    time_s: float = 0.0
    iterations: int = 0
    solve_time_s: float = 0.0


def level_qp(problem: Problem, k: int, held: list[tuple]) -> DenseQP:
    """Level ``k``'s dense QP with the rows ``held`` (``(A, lower, upper)``) of the levels
    above it."""
    p_mat, c = objective(problem.layout, problem.levels[k].residuals)
    return DenseQP(
        p_mat,
        c,
        np.vstack([problem.A] + [h[0] for h in held]),
        np.concatenate([problem.lower] + [h[1] for h in held]),
        np.concatenate([problem.upper] + [h[2] for h in held]),
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
    """Solve the levels in order, each holding the ones above (see the module docstring),
    with one BLAS thread (:func:`~dqcontrol._blas.single_blas_thread`)."""
    start = time.perf_counter()
    # a warm start kept for other rows is carried to these by name
    backend.set_general_rows(problem.layout.num_vars, problem.inequalities)
    with single_blas_thread():
        result = _solve_levels(problem, backend)
    per_level = result.per_level
    return LevelsResult(
        result.solution, per_level, result.failed_level, time.perf_counter() - start,
        sum(s.iterations for s in per_level), sum(s.solve_time_s for s in per_level),
    )  # fmt: skip


def _solve_levels(problem: Problem, backend: Backend) -> LevelsResult:
    residuals = problem.levels[0].residuals
    split = state_objective(problem.layout, residuals)
    if split is None:
        (p_mat, c), states = level_objective(problem.layout, residuals), None
    else:
        (c, states), p_mat = split, None
    points: list[np.ndarray] = []
    per_level: list[Solution] = []
    best: Solution | None = None
    basis: np.ndarray | None = None  # the null space the next level moves in
    warm = _warm_levels(
        problem,
        backend,
        SplitQP(p_mat, c, problem.general_entries, problem.lower, problem.upper, states),
    )
    if warm is not None:
        per_level = list(warm.solutions)
        points = [s.x for s in per_level if s.x is not None]
        best = per_level[-1]
        basis = warm.basis
        if basis is None and len(points) < len(problem.levels):
            basis = _narrowed(problem, len(points) - 1, warm.last_basis, warm.last_held)
    for k in range(len(points), len(problem.levels)):
        held = None  # level k's held rows in the basis, where the reduced level gave them
        if k == 0:
            if p_mat is None:
                assert states is not None, "P not formed comes with its state form"
                p_mat = dense_hessian(states)
            sol = backend.solve(0, DenseQP(p_mat, c, problem.A, problem.lower, problem.upper))
        else:
            assert basis is not None, "a lower level has the basis of the held rows"
            sol, held = _reduced_level(problem, k, points[-1], basis, backend)
            if not sol.ok:
                sol = _banded_level(problem, k, points, backend)
        per_level.append(sol)
        if not sol.ok:
            if best is None:
                return LevelsResult(sol, tuple(per_level), 0)
            return LevelsResult(best, tuple(per_level), k)
        best = sol
        assert sol.x is not None, "a solved level has its solution"
        points.append(sol.x)
        if k + 1 < len(problem.levels):
            basis = _narrowed(problem, k, basis, held)
    assert best is not None, "a problem has at least one level"
    return LevelsResult(best, tuple(per_level), None)


def _warm_levels(problem: Problem, backend: Backend, first: SplitQP) -> WarmLevels | None:
    """The first levels from a backend that solves them on their last active sets in one
    call (``solve_warm_levels``), for a problem of several levels; ``None`` otherwise."""
    if not backend.solves_warm_levels or len(problem.levels) < 2:
        return None
    lower = tuple(level_rows(level.residuals) for level in problem.levels[1:])
    return backend.solve_warm_levels(first, _held_dense(problem, 0), lower)


def _held_dense(problem: Problem, k: int) -> np.ndarray:
    """Level ``k``'s held rows stacked, dense ``(r, len(z))`` (no rows: ``(0, len(z))``)."""
    mats = [r.dense(problem.layout) for r in problem.levels[k].residuals if r.held]
    if not mats:
        return np.zeros((0, problem.layout.num_vars))
    return mats[0] if len(mats) == 1 else np.vstack(mats)


def _narrowed(
    problem: Problem, k: int, basis: np.ndarray | None, held: np.ndarray | None = None
) -> np.ndarray:
    """The basis of the null space of level ``k``'s held rows within ``basis`` (``None``:
    all variables); ``held``: those rows times ``basis`` where already computed."""
    if basis is not None and basis.shape[1] == 0:
        return basis
    if held is None:
        rows = _held_dense(problem, k)
        if rows.shape[0] == 0:
            return np.eye(problem.layout.num_vars) if basis is None else basis
        if basis is None:
            return null_space(rows)
        held = rows @ basis
    assert basis is not None, "rows in a basis come with the basis"
    if held.shape[0] == 0:
        return basis
    return basis @ null_space(held)


def level_in_basis(problem: Problem, k: int, point: np.ndarray, basis: np.ndarray) -> ReducedQP:
    """Level ``k`` in ``z = point + basis y`` as its parts (its dense QP: ``y`` has no
    bounds of its own, every row of the problem's ``A`` is a general row)."""
    return _reduced(problem, k, point, basis)


def _reduced(problem: Problem, k: int, point: np.ndarray, basis: np.ndarray) -> ReducedQP:
    """Level ``k`` in ``z = point + basis y`` as its parts."""
    rows = level_rows(problem.levels[k].residuals)
    return ReducedQP(rows, basis, point, problem.C, problem.lower, problem.upper)


def _reduced_level(
    problem: Problem, k: int, point: np.ndarray, basis: np.ndarray, backend: Backend
) -> tuple[Solution, np.ndarray | None]:
    """Level ``k`` in the null space of the held rows (backend key ``(k, dim)``), and the
    level's held rows in ``basis``; the solution and duals are those of the whole
    problem. A backend with ``solve_reduced`` is given the level's parts, any other its
    dense QP."""
    dim = basis.shape[1]
    if dim == 0:  # the levels above leave no freedom
        return Solution(True, "solved", 0, 0.0, point.copy(), None), None
    reduced = _reduced(problem, k, point, basis)
    sol, held = backend.solve_reduced((k, dim), reduced)
    if not sol.ok or sol.x is None:
        return sol, held
    duals = None if sol.duals is None else sol.duals[dim:]
    return sol._replace(x=point + basis @ sol.x, duals=duals), held


def _banded_level(problem: Problem, k: int, points: list[np.ndarray], backend: Backend) -> Solution:
    """Level ``k`` over all variables with each level ``j < k`` held within its tolerance
    of its value at ``points[j]`` (backend key ``(k, "band")``)."""
    band = [held_rows(problem, j, z) for j, z in enumerate(points)]
    return backend.solve((k, "band"), level_qp(problem, k, [r for r in band if r is not None]))


def residual_values(problem: Problem, z: np.ndarray) -> list[dict[str, float]]:
    """``{term name: ‖A z - b‖}`` per level (diagnostics and tests)."""
    out = []
    for lev in problem.levels:
        out.append(
            {r.name: float(np.linalg.norm(r.value(problem.layout, z))) for r in lev.residuals}
        )
    return out
