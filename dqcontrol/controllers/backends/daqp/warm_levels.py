"""Every priority level solved on its last active set in one compiled call (docs/theory.md
§7.5).

:func:`~dqcontrol.controllers.core.levels.solve_levels` solves the first level, narrows the null
space of its held rows, solves the next level reduced to it, and so on, each step a
compiled kernel with Python between them. While every level's active set stays what it was
at the last step (the usual case in a control loop), :func:`warm_levels` runs the same
kernels in the same order in one call: the first level on its last set
(:func:`~dqcontrol.controllers.backends.daqp.active_set.solve_on_active_set`), each null space
(:func:`~dqcontrol.controllers.linalg.null_space.compiled_null_space`), each lower level
(:func:`~dqcontrol.controllers.backends.daqp.reduced_active_set.reduced_on_active_set`). Its
answers are theirs bit for bit. It stops at the first level that needs more (a set that
fails its check, a null space for LAPACK, a last set of another size) and says where, so
that the caller goes on from there as without it.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.backends.daqp.active_set import SOLVED, solve_on_active_set
from dqcontrol.controllers.backends.daqp.clear_rows import clear_level, row_starts
from dqcontrol.controllers.backends.daqp.reduced_active_set import reduced_on_active_set
from dqcontrol.controllers.linalg.null_space import compiled_null_space

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
    first: tuple,
    held: np.ndarray,
    lower_levels: tuple,
    last: tuple,
    general: np.ndarray,
    settings: np.ndarray,
    out: tuple,
) -> tuple:
    """The levels from the first on, each on its last active set, until one needs more.

    ``first = (factor, c, lower, upper)``: the first level (a factor tuple of ``P``,
    :mod:`.active_set`; the rows ``[I; C]``), ``held`` its held rows; ``lower_levels =
    (entries, b, scale, held counts)``: each lower level's stacked rows, reduced to the null
    space of the rows held above, under the same rows (``general``: the non-zero entries of
    ``C``); ``last = (actives, at_upper, dims)``: each level's last set (a lower level's
    dimension, ``-1`` for none); ``settings = (primal_tol, dual_tol, max_changes,
    pivot_share, max_dim)``. Writes each solved level into ``out = (points, duals,
    has_duals, changes)``; returns ``(done, actives, at_upper, counts, dims, basis, ready,
    held_rows)``: the levels solved, their sets (``counts`` rows each) and dimensions; with
    ``ready`` the basis the next level moves in, else the last level's basis and its held
    rows in it (empty after the first), which the caller narrows with LAPACK."""
    n = first[1].shape[0]
    levels = 1 + len(lower_levels[0])
    counts = np.zeros(levels, dtype=np.int64)
    dims = np.full(levels, n, dtype=np.int64)
    none = np.zeros((0, 0))
    starts = row_starts(general, first[2].shape[0] - n)  # for every lower level
    solved, actives, uppers, point = _first_level(
        first, general, last[0][0], last[1][0], settings, out
    )
    if not solved:
        return 0, actives[:0], uppers[:0], counts, dims, none, False, none
    counts[0] = actives.shape[0]
    outcome, basis = compiled_null_space(held)
    previous, rows_held = none, none
    for k in range(1, levels):
        if outcome != _DONE:
            return k, actives, uppers, counts, dims, previous, False, rows_held
        dim = basis.shape[1]
        dims[k] = dim
        if dim == 0:  # the levels above leave no freedom
            out[0][k] = point
            continue
        if last[2][k - 1] != dim or dim > int(settings[4]):
            return k, actives, uppers, counts, dims, basis, True, none
        solved, point, active, at_upper, rows_held = _lower_level(
            k, lower_levels, basis, point, general, starts, first, last, settings, out
        )
        if not solved:
            return k, actives, uppers, counts, dims, basis, True, none
        counts[k] = active.shape[0]
        actives = np.concatenate((actives, active))
        uppers = np.concatenate((uppers, at_upper))
        previous = basis
        if k + 1 < levels and rows_held.shape[0] > 0:
            outcome, narrow = compiled_null_space(rows_held)
            if outcome == _DONE:
                basis = basis @ narrow
    return levels, actives, uppers, counts, dims, basis, True, none


@compiled
def _keep(out: tuple, k: int, point: np.ndarray, duals: np.ndarray, changes: int) -> None:
    """Level ``k``'s point, multipliers and set changes into ``out``."""
    out[0][k] = point
    out[1][k] = duals
    out[2][k] = True
    out[3][k] = changes


@compiled
def _first_level(
    first: tuple, entries: np.ndarray, active: np.ndarray, at_upper: np.ndarray, settings, out
) -> tuple:
    """The first level on its last set (its check over the non-zero ``entries`` of
    ``C``): ``(solved, active, at_upper, point)``."""
    factor, c, lower, upper = first
    z, duals = np.empty(c.shape[0]), np.empty(lower.shape[0])
    general = np.zeros((0, c.shape[0]))  # C is read from its entries
    if not _within(lower, upper):
        return False, active, at_upper, z
    status, active, at_upper, count = solve_on_active_set(
        factor, c, general, entries, True, lower, upper, active, at_upper,
        settings[0], settings[1], int(settings[2]), z, duals,
    )  # fmt: skip
    if status != SOLVED or not _finite(z):
        return False, active, at_upper, z
    _keep(out, 0, z, duals, count)
    return True, active, at_upper, z


@compiled
def _lower_level(
    k: int,
    lower_levels: tuple,
    basis: np.ndarray,
    point: np.ndarray,
    general: np.ndarray,
    starts: np.ndarray,
    first: tuple,
    last: tuple,
    settings: np.ndarray,
    out: tuple,
) -> tuple:
    """Lower level ``k`` in ``z = point + basis y`` (``starts``: where each row of ``C``
    starts in ``general``) on its last set, checked over the rows
    near their bounds (:func:`~dqcontrol.controllers.backends.daqp.clear_rows.clear_level`);
    where the set does not hold as it is, solved in full
    (:func:`~dqcontrol.controllers.backends.daqp.reduced_active_set.reduced_on_active_set`):
    ``(solved, point, active, at_upper, held rows in the basis)``."""
    lower, upper = first[2], first[3]
    dim = basis.shape[1]
    size = dim + lower.shape[0]
    b = lower_levels[1][k - 1]
    rows = np.empty((b.shape[0], dim + 1))
    y, duals = np.empty(dim), np.empty(size)
    active, at_upper, count = last[0][k], last[1][k], 0
    if not clear_level(
        lower_levels[0][k - 1], b, lower_levels[2][k - 1], basis, point, general, starts,
        lower, upper, active, at_upper, settings, rows, y, duals,
    ):  # fmt: skip
        qp_rows, qp_lower, qp_upper = np.empty((size, dim)), np.empty(size), np.empty(size)
        status, active, at_upper, count, _h, _g = reduced_on_active_set(
            lower_levels[0][k - 1], b, lower_levels[2][k - 1], basis, point, general, lower,
            upper, active, at_upper, settings, rows, qp_rows, qp_lower, qp_upper, y, duals,
        )  # fmt: skip
        if status != SOLVED or not _finite(y):
            return False, point, active, at_upper, np.zeros((0, 0))
    point = point + basis @ y
    _keep(out, k, point, duals[dim:], count)
    held = lower_levels[3][k - 1]
    return True, point, active, at_upper, np.ascontiguousarray(rows[:held, :-1])
