"""A reduced level whose last active set was empty, checked without its rows in the basis
(docs/theory.md §7.5).

A lower level in ``z = point + Z y`` is a QP in ``y`` under the rows ``[I; C] Z`` of the
problem: forming them costs a product with ``Z`` for every row, and checking its
unconstrained optimum costs another. Most of those rows are far from their bounds. Here the
optimum ``y`` is checked in ``z`` first, over ``[I; C]`` (sparse) at ``z = point + Z y``:
a row well inside its bounds there, by more than rounding can move the value the reduced
check would compute, passes that check too, and is not formed at all. Only the rows near
or beyond a bound are formed in the basis, each exactly as
:func:`~dqcontrol.controllers.reduced.rows_in_basis` forms it, and checked as
:func:`~dqcontrol.controllers.backends.active_set.solve_on_active_set` checks it. The
answer is therefore the one of the full check bit for bit; where a row breaks its bound
the caller solves the level in full instead.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.backends.active_set import _breach, _equality_optimum
from dqcontrol.controllers.cholesky import cholesky_into
from dqcontrol.controllers.reduced import _entry_rows, _weighted_gram

__all__ = ["clear_unconstrained_level"]

#: Bound on the relative difference between a row's value computed in ``z`` and in ``y``
#: (sums of at most a few hundred products of ``float64``: some ``1e-14``), with room.
_ROUNDING = 1e-12


@compiled
def _row_in_basis(
    r: int, entries: np.ndarray, starts: np.ndarray, basis: np.ndarray, point: np.ndarray,
    line: np.ndarray,
) -> float:  # fmt: skip
    """Row ``r`` of ``[I; C]`` times ``basis`` into ``line`` and the row times ``point``,
    each sum as :func:`~dqcontrol.controllers.reduced.rows_in_basis` forms it."""
    nv, dim = basis.shape
    if r < nv:
        for c in range(dim):
            line[c] = basis[r, c]
        return point[r]
    line[:] = 0.0
    shift = 0.0
    for e in range(starts[r - nv], starts[r - nv + 1]):
        j, v = int(entries[e, 1]), entries[e, 2]
        for c in range(dim):
            line[c] += v * basis[j, c]
        shift += v * point[j]
    return shift


@compiled
def _breaks(
    r: int, entries: np.ndarray, starts: np.ndarray, basis: np.ndarray, point: np.ndarray,
    lower: np.ndarray, upper: np.ndarray, y: np.ndarray, tol: float, line: np.ndarray,
) -> bool:  # fmt: skip
    """Whether row ``r``, formed in the basis, breaks its bounds in ``y`` beyond ``tol``
    (the check of ``solve_on_active_set`` while no row has broken its bounds)."""
    shift = _row_in_basis(r, entries, starts, basis, point, line)
    if r < basis.shape[0]:
        low, up = lower[r] - point[r], upper[r] - point[r]
    else:
        low, up = lower[r] - shift, upper[r] - shift
    value = 0.0
    for c in range(y.shape[0]):
        value += line[c] * y[c]
    if low - tol <= value <= up + tol:
        return False
    norm2 = 0.0
    for c in range(y.shape[0]):
        norm2 += line[c] * line[c]
    return _breach(value, norm2, low, up, tol)[0] > 0.0


@compiled
def _row_starts(entries: np.ndarray, rows: int) -> np.ndarray:
    """Where each row's entries start (``rows + 1`` offsets into ``entries``)."""
    starts = np.zeros(rows + 1, dtype=np.int64)
    for e in range(entries.shape[0]):
        starts[int(entries[e, 0]) + 1] += 1
    for i in range(rows):
        starts[i + 1] += starts[i]
    return starts


@compiled
def _clear(low: float, up: float, value: float, size: float, tol: float) -> bool:
    """A row of value ``value`` in ``z`` within ``[low, up]`` widened by ``tol``, with room
    for the rounding of values of size ``size``."""
    room = _ROUNDING * (size + (abs(low) if np.isfinite(low) else 0.0))
    room += _ROUNDING * (abs(up) if np.isfinite(up) else 0.0)
    return low - tol + room <= value <= up + tol - room


@compiled
def _all_rows_hold(
    entries: np.ndarray, basis: np.ndarray, point: np.ndarray, lower: np.ndarray,
    upper: np.ndarray, y: np.ndarray, tol: float,
) -> bool:  # fmt: skip
    """Whether ``y`` is finite and every row of ``[I; C]`` (``entries``: those of ``C``)
    holds at it in the check of ``solve_on_active_set``: first in ``z``, then, for rows
    near a bound, in the basis."""
    nv, dim = basis.shape
    y_size = 0.0
    for c in range(dim):
        if not np.isfinite(y[c]):
            return False
        y_size += abs(y[c])
    z = np.empty(nv)
    for j in range(nv):
        s = 0.0
        for c in range(dim):
            s += basis[j, c] * y[c]
        z[j] = point[j] + s
    starts = _row_starts(entries, lower.shape[0] - nv)
    line = np.empty(dim)
    for r in range(lower.shape[0]):
        if r < nv:
            value, size = z[r], abs(point[r]) + abs(z[r]) + y_size
        else:
            value, size = 0.0, 0.0
            for e in range(starts[r - nv], starts[r - nv + 1]):
                j, v = int(entries[e, 1]), abs(entries[e, 2])
                value += entries[e, 2] * z[j]
                size += v * (abs(point[j]) + abs(z[j]) + y_size)
        if _clear(lower[r], upper[r], value, size, tol):
            continue
        if _breaks(r, entries, starts, basis, point, lower, upper, y, tol, line):
            return False
    return True


@compiled
def clear_unconstrained_level(
    entries: np.ndarray, b: np.ndarray, scale: np.ndarray, basis: np.ndarray,
    point: np.ndarray, general: np.ndarray, lower: np.ndarray, upper: np.ndarray,
    settings: np.ndarray, rows: np.ndarray, y: np.ndarray,
) -> bool:  # fmt: skip
    """The level of the stacked rows (``entries``, ``b``, ``scale``) in ``z = point + basis
    y`` under ``[I; C]`` (``general``: the entries of ``C``, bounds ``lower``/``upper``
    valid), solved on the empty active set: its rows ``[A basis | A point - b]`` into
    ``rows`` and, where its unconstrained optimum holds every row, that optimum into ``y``
    and True (what :func:`~dqcontrol.controllers.backends.reduced_active_set.
    reduced_on_active_set` answers from an empty guess with no change, bit for bit).
    False where it does not, or the Hessian is not safely positive definite: the caller
    then solves the level in full."""
    row_scale = np.empty(rows.shape[0])
    _entry_rows(entries, basis, point, b, 1.0, scale, rows, row_scale)
    hessian, gradient = _weighted_gram(rows, row_scale)
    factor = np.zeros(hessian.shape)
    if not cholesky_into(hessian, factor, settings[3], 0.0):
        return False
    none, sides = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.bool_)
    no_rows = np.zeros((0, hessian.shape[0]))
    _equality_optimum(factor, gradient, no_rows, lower, upper, none, sides, y, np.zeros(0))
    return _all_rows_hold(general, basis, point, lower, upper, y, settings[0])
