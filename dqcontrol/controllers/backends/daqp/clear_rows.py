"""A reduced level solved on its last active set, checked without all its rows in the
basis (docs/theory.md §7.5).

A lower level in ``z = point + Z y`` is a QP in ``y`` under the rows ``[I; C] Z`` of the
problem: forming them costs a product with ``Z`` for every row, and checking the optimum on
the level's last set costs another. Only the set's rows are needed to find that optimum,
and most of the others are far from their bounds. Here the set's rows are formed in the
basis, the optimum found from them, and checked in ``z`` first, over ``[I; C]`` (sparse) at
``z = point + Z y``: a row well inside its bounds there, by more than rounding can move the
value the reduced check would compute, passes that check too, and is not formed at all.
Only the rows near or beyond a bound are formed in the basis, each exactly as
:func:`~dqcontrol.controllers.core.reduced.rows_in_basis` forms it, and checked as
:func:`~dqcontrol.controllers.backends.daqp.active_set.solve_on_active_set` checks it. The
answer is therefore the one of the full check bit for bit; where a row breaks its bound,
or a multiplier has the wrong sign, the caller solves the level in full instead (which
mends the set).
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.backends.daqp.active_set import (
    _breach,
    _equality_optimum,
    _worst_multiplier,
    dense_factor,
)
from dqcontrol.controllers.core.reduced import _entry_rows, _weighted_gram
from dqcontrol.controllers.linalg.cholesky import cholesky_into

__all__ = ["clear_level", "row_starts"]

#: Bound on the relative difference between a row's value computed in ``z`` and in ``y``
#: (sums of at most a few hundred products of ``float64``: some ``1e-14``), with room.
_ROUNDING = 1e-12


@compiled
def _row_in_basis(
    r: int, entries: np.ndarray, starts: np.ndarray, basis: np.ndarray, point: np.ndarray,
    line: np.ndarray,
) -> float:  # fmt: skip
    """Row ``r`` of ``[I; C]`` times ``basis`` into ``line`` and the row times ``point``,
    each sum as :func:`~dqcontrol.controllers.core.reduced.rows_in_basis` forms it."""
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
def row_starts(entries: np.ndarray, rows: int) -> np.ndarray:
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
    entries: np.ndarray, starts: np.ndarray, basis: np.ndarray, point: np.ndarray,
    lower: np.ndarray, upper: np.ndarray, y: np.ndarray, tol: float,
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
def _set_rows(
    active: np.ndarray, entries: np.ndarray, starts: np.ndarray, basis: np.ndarray,
    point: np.ndarray, lower: np.ndarray, upper: np.ndarray, qp_lower: np.ndarray,
    qp_upper: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """The rows ``active`` of the level's QP in ``y`` (``[I; [I; C] Z]``), dense ``(k,
    dim)``, and their bounds into ``qp_lower``/``qp_upper`` (the other entries are not
    written), each as :func:`~dqcontrol.controllers.core.reduced.rows_in_basis` forms it."""
    dim = basis.shape[1]
    held = np.zeros((active.shape[0], dim))
    line = np.empty(dim)
    for j in range(active.shape[0]):
        a = active[j]
        if a < dim:  # a bound of y of its own: none
            held[j, a] = 1.0
            qp_lower[a], qp_upper[a] = -np.inf, np.inf
            continue
        r = a - dim
        shift = _row_in_basis(r, entries, starts, basis, point, line)
        held[j] = line
        if r < basis.shape[0]:
            qp_lower[a], qp_upper[a] = lower[r] - point[r], upper[r] - point[r]
        else:
            qp_lower[a], qp_upper[a] = lower[r] - shift, upper[r] - shift
    return held


@compiled
def clear_level(
    entries: np.ndarray, b: np.ndarray, scale: np.ndarray, basis: np.ndarray,
    point: np.ndarray, general: np.ndarray, starts: np.ndarray, lower: np.ndarray,
    upper: np.ndarray, active: np.ndarray, at_upper: np.ndarray, settings: np.ndarray,
    rows: np.ndarray, y: np.ndarray, duals: np.ndarray,
) -> bool:  # fmt: skip
    """The level of the stacked rows (``entries``, ``b``, ``scale``) in ``z = point + basis
    y`` under ``[I; C]`` (``general``: the entries of ``C``, ``starts`` where each of its
    rows starts there, :func:`row_starts`; bounds ``lower``/``upper`` valid), solved on the
    set ``active``/``at_upper`` (rows of the QP in ``y``): its rows ``[A basis | A point -
    b]`` into ``rows`` and, where that optimum holds every row and every multiplier has its
    sign, the optimum into ``y``, the multipliers into ``duals`` and True: what
    ``reduced_on_active_set`` answers from that set with no change, bit for bit. False where
    it does not, the set's rows are dependent or the Hessian is not safely positive
    definite: the caller then solves the level in full."""
    row_scale = np.empty(rows.shape[0])
    _entry_rows(entries, basis, point, b, 1.0, scale, rows, row_scale)
    hessian, gradient = _weighted_gram(rows, row_scale)
    factor = np.zeros(hessian.shape)
    if not cholesky_into(hessian, factor, settings[3], 0.0):
        return False
    qp_lower, qp_upper = np.empty(duals.shape[0]), np.empty(duals.shape[0])
    held = _set_rows(active, general, starts, basis, point, lower, upper, qp_lower, qp_upper)
    lam = np.zeros(active.shape[0])
    factors = dense_factor(factor)
    if not _equality_optimum(factors, gradient, held, qp_lower, qp_upper, active, at_upper, y, lam):
        return False
    if not _all_rows_hold(general, starts, basis, point, lower, upper, y, settings[0]):
        return False
    if _worst_multiplier(qp_lower, qp_upper, active, at_upper, lam, settings[1]) >= 0:
        return False
    duals[:] = 0.0
    for i in range(active.shape[0]):
        duals[active[i]] = lam[i]
    return True
