"""Every priority level solved on its last active set in one compiled call (docs/theory.md
§7.5).

:func:`~dqcontrol.controllers.levels.solve_levels` solves the first level, narrows the null
space of its held rows, solves the next level reduced to it, and so on, each step a
compiled kernel with Python between them. While every level's active set stays what it was
at the last step (the usual case in a control loop), :func:`warm_levels` runs the same
kernels in the same order in one call: the first level on its last set
(:func:`~dqcontrol.controllers.backends.active_set.solve_on_active_set`), each null space
(:func:`~dqcontrol.controllers.null_space.compiled_null_space`), each lower level
(:func:`~dqcontrol.controllers.backends.reduced_active_set.reduced_on_active_set`). Its
answers are theirs bit for bit. It stops at the first level that needs more (a set that
fails its check, a null space for LAPACK, a last set of another size) and says where, so
that the caller goes on from there as without it.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.backends.active_set import SOLVED, solve_on_active_set
from dqcontrol.controllers.backends.reduced_active_set import reduced_on_active_set
from dqcontrol.controllers.null_space import compiled_null_space

__all__ = ["warm_levels"]

_DONE = 0  # compiled_null_space's outcome with a basis


@compiled
def _finite(values: np.ndarray) -> bool:
    for v in values:
        if not np.isfinite(v):
            return False
    return True


@compiled
def _within(lower: np.ndarray, upper: np.ndarray) -> bool:
    """Every lower bound at most its upper one (not NaN)."""
    for i in range(lower.shape[0]):
        if not lower[i] <= upper[i]:
            return False
    return True


@compiled
def warm_levels(
    factor: np.ndarray,
    c: np.ndarray,
    a: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    held: np.ndarray,
    level_entries: tuple,
    level_b: tuple,
    level_scale: tuple,
    level_held: np.ndarray,
    last_active: tuple,
    last_upper: tuple,
    last_dims: np.ndarray,
    general: np.ndarray,
    settings: np.ndarray,
    max_dim: int,
    points: np.ndarray,
    duals: np.ndarray,
    changes: np.ndarray,
    has_duals: np.ndarray,
) -> tuple:
    """The levels from the first on, each on its last active set, until one needs more.

    The first level is ``min ½ zᵀ P z + cᵀ z`` (``factor``: ``L`` with ``P = L Lᵀ``) under
    ``lower ≤ a z ≤ upper`` (``a = [I; C]``) from the set ``last_active[0]`` /
    ``last_upper[0]``; ``held`` are its held rows. Lower level ``k`` (``k ≥ 1``) is given
    by its stacked rows (``level_entries[k - 1]``, ``level_b``, ``level_scale``, the
    first ``level_held[k - 1]`` of them held), reduced to the null space of the rows held
    above, under the same rows (``general``: the non-zero entries of ``C``), from its last
    set of ``last_dims[k - 1]`` variables (none: ``-1``; more than ``max_dim``: not
    here). ``settings``: ``(primal_tol, dual_tol, max_changes, pivot_share)``.

    Writes each solved level's point into ``points[k]``, its multipliers of the rows
    ``a`` into ``duals[k]`` (``has_duals[k]``: a level without freedom has none) and its
    set's changes into ``changes[k]``. Returns ``(done, actives, at_upper, counts, dims,
    basis, basis_ready, last_basis, last_held)``: how many levels were solved; their
    active sets concatenated (``counts`` rows each) and the null-space dimension each was
    solved in; the basis the next level moves in where ``basis_ready``, otherwise the
    basis of the last level solved and its held rows in it, from which the caller narrows
    it with LAPACK.
    """
    n = c.shape[0]
    levels = 1 + len(level_entries)
    counts = np.zeros(levels, dtype=np.int64)
    dims = np.full(levels, n, dtype=np.int64)
    kept_active = np.zeros(0, dtype=np.int64)
    kept_upper = np.zeros(0, dtype=np.bool_)
    empty = np.zeros((n, 0))
    if not _within(lower, upper):
        return 0, kept_active, kept_upper, counts, dims, empty, False, empty, np.zeros((0, 0))
    z = np.empty(n)
    row_duals = np.empty(a.shape[0])
    status, active, at_upper, count = solve_on_active_set(
        factor, c, a, lower, upper, last_active[0], last_upper[0],
        settings[0], settings[1], int(settings[2]), z, row_duals,
    )  # fmt: skip
    if status != SOLVED or not _finite(z):
        return 0, kept_active, kept_upper, counts, dims, empty, False, empty, np.zeros((0, 0))
    points[0] = z
    duals[0] = row_duals
    has_duals[0] = True
    changes[0] = count
    counts[0] = active.shape[0]
    kept_active = np.concatenate((kept_active, active))
    kept_upper = np.concatenate((kept_upper, at_upper))
    outcome, basis = compiled_null_space(held)
    if outcome != _DONE:
        return 1, kept_active, kept_upper, counts, dims, empty, False, empty, np.zeros((0, 0))
    point = z
    for k in range(1, levels):
        dim = basis.shape[1]
        dims[k] = dim
        rows_held = np.zeros((0, 0))
        if dim == 0:
            points[k] = point
            has_duals[k] = False
            changes[k] = 0
        else:
            if last_dims[k - 1] != dim or dim > max_dim:
                return k, kept_active, kept_upper, counts, dims, basis, True, empty, rows_held
            solved, y, y_duals, active, at_upper, count, rows_held = _lower_level(
                level_entries[k - 1], level_b[k - 1], level_scale[k - 1], level_held[k - 1],
                basis, point, general, lower, upper, last_active[k], last_upper[k], settings,
            )  # fmt: skip
            if not solved:
                return k, kept_active, kept_upper, counts, dims, basis, True, empty, rows_held
            point = point + basis @ y
            points[k] = point
            duals[k] = y_duals[dim:]
            has_duals[k] = True
            changes[k] = count
            counts[k] = active.shape[0]
            kept_active = np.concatenate((kept_active, active))
            kept_upper = np.concatenate((kept_upper, at_upper))
        if k + 1 == levels or dim == 0 or rows_held.shape[0] == 0:
            continue
        outcome, narrow = compiled_null_space(rows_held)
        if outcome != _DONE:
            return k + 1, kept_active, kept_upper, counts, dims, empty, False, basis, rows_held
        basis = basis @ narrow
    return levels, kept_active, kept_upper, counts, dims, basis, True, empty, np.zeros((0, 0))


@compiled
def _lower_level(
    entries: np.ndarray,
    b: np.ndarray,
    scale: np.ndarray,
    held: int,
    basis: np.ndarray,
    point: np.ndarray,
    general: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    active: np.ndarray,
    at_upper: np.ndarray,
    settings: np.ndarray,
) -> tuple:
    """A lower level in ``z = point + basis y`` on its last active set
    (:func:`~dqcontrol.controllers.backends.reduced_active_set.reduced_on_active_set`):
    ``(solved, y, duals, active, at_upper, changes, held rows in the basis)``."""
    dim = basis.shape[1]
    size = dim + lower.shape[0]
    rows = np.empty((b.shape[0], dim + 1))
    qp_rows = np.empty((size, dim))
    qp_lower = np.empty(size)
    qp_upper = np.empty(size)
    y = np.empty(dim)
    duals = np.empty(size)
    status, active, at_upper, count, _h, _g = reduced_on_active_set(
        entries, b, scale, basis, point, general, lower, upper, active, at_upper, settings,
        rows, qp_rows, qp_lower, qp_upper, y, duals,
    )  # fmt: skip
    solved = status == SOLVED and _finite(y)
    return solved, y, duals, active, at_upper, count, np.ascontiguousarray(rows[:held, :-1])
