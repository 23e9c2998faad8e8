"""A level's objective and rows in the null space of the levels above (docs/theory.md §7.4).

With ``z = z₀ + Z y``, a residual's rows ``A z - b`` become ``(A Z) y + (A z₀ - b)``: the
reduced level's Hessian and gradient are sums over the rows of ``A Z`` and ``A z₀ - b``
(each residual's ``2 w`` and row weights), never the ``n × n`` Hessian of the whole
level. The level's residuals are stacked once as the non-zero entries of their rows
(:func:`level_rows`; kept while the rows are read-only), so ``A Z`` skips every zero in one
compiled pass. The general rows of the limits ``C Z`` skip ``C``'s zeros
too (the coupling of neighbouring intervals, a trust region: a few entries per row); a
read-only ``C`` gives its non-zero entries once (:func:`~dqcontrol.controllers.linalg.gram.kept`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.core.problem import DenseQP, Residual
from dqcontrol.controllers.linalg.entries import _nonzero_entries, nonzero_entries
from dqcontrol.controllers.linalg.gram import frozen

__all__ = [
    "LevelRows",
    "ReducedObjective",
    "ReducedQP",
    "level_rows",
    "nonzero_entries",
    "objective_in_basis",
    "reduced_objective",
    "rows_in_basis",
    "sparse_product",
]


class ReducedObjective(NamedTuple):
    """A level's ``½ yᵀ H y + gᵀ y`` in the basis, and its held rows ``R Z`` there."""

    hessian: np.ndarray
    gradient: np.ndarray
    held: np.ndarray


@compiled
def _finish_row(
    out: np.ndarray, row: int, b: np.ndarray, w2: float, row_weights: np.ndarray, scale: np.ndarray
) -> None:
    """The row's value minus ``b`` in the last column, its scale ``w2`` times its weight
    (``row_weights`` empty: 1)."""
    out[row, out.shape[1] - 1] -= b[row]
    scale[row] = w2 * row_weights[row] if row_weights.size else w2


@compiled
def _add_row(line: np.ndarray, v: float, basis: np.ndarray, point: np.ndarray, j: int) -> None:
    """``line += v [basis[j] | point[j]]``."""
    dim = basis.shape[1]
    source = basis[j]
    for c in range(dim):
        line[c] += v * source[c]
    line[dim] += v * point[j]


@compiled
def _entry_product(entries: np.ndarray, right: np.ndarray, out: np.ndarray) -> None:
    """``out = a @ right`` from the non-zero entries of ``a`` (:func:`nonzero_entries`)."""
    cols = right.shape[1]
    out[:] = 0.0
    for e in range(entries.shape[0]):
        line = out[int(entries[e, 0])]
        source = right[int(entries[e, 1])]
        v = entries[e, 2]
        for c in range(cols):
            line[c] += v * source[c]


@compiled
def _entry_rows(
    entries: np.ndarray,
    basis: np.ndarray,
    point: np.ndarray,
    b: np.ndarray,
    w2: float,
    row_weights: np.ndarray,
    out: np.ndarray,
    scale: np.ndarray,
) -> None:
    """``out = [A basis | A point - b]`` from the non-zero entries of ``A``, and the rows'
    scales."""
    out[:] = 0.0
    for e in range(entries.shape[0]):
        _add_row(out[int(entries[e, 0])], entries[e, 2], basis, point, int(entries[e, 1]))
    for row in range(out.shape[0]):
        _finish_row(out, row, b, w2, row_weights, scale)


def sparse_product(a: np.ndarray, right: np.ndarray) -> np.ndarray:
    """``a @ right`` (``right`` 2-D) skipping the zeros of ``a``: each entry of the result
    sums its non-zero products in column order."""
    out = np.empty((a.shape[0], right.shape[1]))
    _entry_product(nonzero_entries(a), right, out)
    return out


@compiled
def _weighted_gram(rows: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(Mᵀ S M, Mᵀ S e)`` for ``rows = [M | e]`` and ``S = diag(scale)`` (one product;
    the first symmetric, from its upper triangle)."""
    dim = rows.shape[1] - 1
    weighted = np.empty((rows.shape[0], dim))
    for k in range(rows.shape[0]):
        for a in range(dim):
            weighted[k, a] = scale[k] * rows[k, a]
    both = weighted.T @ rows
    hessian = np.empty((dim, dim))
    gradient = np.empty(dim)
    for a in range(dim):
        gradient[a] = both[a, dim]
        for b in range(dim):
            hessian[a, b] = both[a, b] if b >= a else both[b, a]
    return hessian, gradient


class LevelRows(NamedTuple):
    """A level's residuals stacked: the held ones first, then the others that weigh.

    Attributes:
        entries: the non-zero entries of the stacked rows ``A``, ``(nnz, 3)``: row, column,
            value (row by row, columns in order).
        b: the stacked ``b``.
        scale: each row's ``2 w`` times its row weight.
        held: how many rows (the first) the lower levels hold.
    """

    entries: np.ndarray
    b: np.ndarray
    scale: np.ndarray
    held: int


@compiled
def _block_entries(blocks: np.ndarray) -> np.ndarray:
    """:func:`nonzero_entries` of the block-diagonal rows of ``blocks`` ``(p, r, m)``."""
    p, r, m = blocks.shape
    count = 0
    for i in range(p):
        for a in range(r):
            for k in range(m):
                count += blocks[i, a, k] != 0.0
    out = np.empty((count, 3))
    e = 0
    for i in range(p):
        for a in range(r):
            for k in range(m):
                v = blocks[i, a, k]
                if v != 0.0:
                    out[e, 0] = i * r + a
                    out[e, 1] = i * m + k
                    out[e, 2] = v
                    e += 1
    return out


def _stacked_entries(arrays: tuple[np.ndarray, ...], kinds: tuple[bool, ...]) -> np.ndarray:
    """The entries of residual rows ``arrays`` (``kinds[i]``: the array is ``blocks``), each
    one's rows after the previous ones'."""
    parts, start = [], 0
    for rows, is_blocks in zip(arrays, kinds, strict=True):
        entries = _block_entries(rows) if is_blocks else _nonzero_entries(rows)
        entries[:, 0] += start
        parts.append(entries)
        start += rows.shape[0] * rows.shape[1] if is_blocks else rows.shape[0]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def _row_scale(r: Residual) -> np.ndarray:
    w2 = 2.0 * r.weight
    return np.full(r.b.size, w2) if r.row_weights is None else w2 * r.row_weights


def _static_rows(used: list[Residual]) -> tuple[np.ndarray, np.ndarray]:
    """The entries and the row scales of the stacked residuals ``used``."""
    operands = tuple(_rows_of(r) for r in used)
    kinds = tuple(r.blocks is not None for r in used)
    entries = _stacked_entries(operands, kinds)
    return frozen(entries), frozen(np.concatenate([_row_scale(r) for r in used]))


#: ``(rows, weight, row weights) of each residual, by id -> (those arrays, the entries,
#: the row scales)``: the parts of :class:`LevelRows` that stay while a level's rows are
#: read-only and its weights the same. An entry holds its arrays, so that no other array
#: takes their ids while it is kept (at most :data:`_STATIC_CAPACITY` entries).
_STATIC: dict[tuple, tuple[tuple, np.ndarray, np.ndarray]] = {}
_STATIC_CAPACITY = 64


def _rows_of(r: Residual) -> np.ndarray:
    """The residual's ``blocks``, or its ``A``."""
    rows = r.blocks if r.blocks is not None else r.A
    assert rows is not None, "a residual has A or blocks"
    return rows


def _kept_static(used: list[Residual]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_static_rows`, kept while every residual's rows and row weights are
    read-only."""
    arrays = [a for r in used for a in (_rows_of(r), r.row_weights)]
    for a in arrays:
        if a is not None and a.flags.writeable:
            return _static_rows(used)
    key = (*map(id, arrays), *(r.weight for r in used))
    entry = _STATIC.get(key)
    if entry is not None:  # the entry holds its arrays: their ids name no other array
        return entry[1], entry[2]
    if len(_STATIC) >= _STATIC_CAPACITY:
        _STATIC.clear()
    entries, scale = _static_rows(used)
    _STATIC[key] = (tuple(arrays), entries, scale)
    return entries, scale


_EMPTY_ENTRIES = frozen(np.zeros((0, 3)))


def level_rows(residuals: tuple[Residual, ...]) -> LevelRows:
    """The :class:`LevelRows` of a level's residuals (the entries and row scales computed
    once while every residual's rows are read-only and the weights stay the same)."""
    held, others, count = [], [], 0
    for r in residuals:
        if r.held:
            held.append(r)
            count += r.b.size
        elif 2.0 * r.weight != 0.0:
            others.append(r)
    used = held + others
    if not used:
        return LevelRows(_EMPTY_ENTRIES, np.zeros(0), frozen(np.zeros(0)), 0)
    entries, scale = _kept_static(used)
    return LevelRows(entries, np.concatenate([r.b for r in used]), scale, count)


def objective_in_basis(rows: LevelRows, point: np.ndarray, basis: np.ndarray) -> ReducedObjective:
    """``Σ w ‖A (point + basis y) - b‖²`` of the stacked ``rows`` as ``½ yᵀ H y + gᵀ y``
    up to a constant, and the held rows ``A basis``."""
    stacked = np.empty((rows.b.size, basis.shape[1] + 1))  # [A basis | A point - b]
    scale = np.empty(rows.b.size)
    _entry_rows(rows.entries, basis, point, rows.b, 1.0, rows.scale, stacked, scale)
    hessian, gradient = _weighted_gram(stacked, scale)
    return ReducedObjective(hessian, gradient, stacked[: rows.held, :-1])


class ReducedQP(NamedTuple):
    """A level's QP in ``y`` with ``z = point + basis y``, as its parts: the level's stacked
    rows, and the rows ``[I; C]`` of the problem (``general``: ``C``; ``lower``/``upper``
    theirs). :meth:`objective` and :meth:`dense` give it as a dense QP; a backend may solve
    it from the parts instead (``solve_reduced``, docs/theory.md §7.5)."""

    rows: LevelRows
    basis: np.ndarray
    point: np.ndarray
    general: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    def objective(self) -> ReducedObjective:
        """The level's objective in ``y`` and its held rows there."""
        return objective_in_basis(self.rows, self.point, self.basis)

    def dense(self, objective: ReducedObjective) -> DenseQP:
        """The dense QP in ``y`` with ``objective``: ``y`` has no bounds of its own, every
        row of ``[I; C]`` is a general row (:func:`rows_in_basis`)."""
        rows, lower, upper = rows_in_basis(
            self.general, self.basis, self.point, self.lower, self.upper
        )
        return DenseQP(objective.hessian, objective.gradient, rows, lower, upper)


def reduced_objective(
    residuals: tuple[Residual, ...], point: np.ndarray, basis: np.ndarray
) -> ReducedObjective:
    """``Σ w ‖A (point + basis y) - b‖²`` as ``½ yᵀ H y + gᵀ y`` up to a constant, and
    the held rows ``A basis`` of the held residuals stacked in order."""
    return objective_in_basis(level_rows(residuals), point, basis)


@compiled
def _rows_in_basis(
    entries: np.ndarray,
    basis: np.ndarray,
    point: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    rows: np.ndarray,
    lower_out: np.ndarray,
    upper_out: np.ndarray,
) -> None:
    """:func:`rows_in_basis` into ``rows``, ``lower_out``, ``upper_out``."""
    nv, dim = basis.shape
    rows[:] = 0.0
    for a in range(dim):
        rows[a, a] = 1.0
        lower_out[a] = -np.inf
        upper_out[a] = np.inf
    for j in range(nv):
        line = rows[dim + j]
        source = basis[j]
        for c in range(dim):
            line[c] = source[c]
        lower_out[dim + j] = lower[j] - point[j]
        upper_out[dim + j] = upper[j] - point[j]
    shift = np.zeros(lower.size - nv)
    for e in range(entries.shape[0]):
        i = int(entries[e, 0])
        j = int(entries[e, 1])
        v = entries[e, 2]
        line = rows[dim + nv + i]
        source = basis[j]
        for c in range(dim):
            line[c] += v * source[c]
        shift[i] += v * point[j]
    for i in range(shift.size):
        lower_out[dim + nv + i] = lower[nv + i] - shift[i]
        upper_out[dim + nv + i] = upper[nv + i] - shift[i]


def rows_in_basis(
    general: np.ndarray, basis: np.ndarray, point: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rows ``[I; C]`` bounding ``z`` (``general``: ``C``; ``lower``/``upper`` theirs)
    in ``y`` with ``z = point + basis y``: ``y``'s own rows ``I`` without bounds, then
    ``[basis; C basis]`` with the bounds shifted by ``[point; C point]``; ``C``'s zeros
    are skipped."""
    nv, dim = basis.shape
    size = dim + nv + general.shape[0]
    rows = np.empty((size, dim))
    lower_out = np.empty(size)
    upper_out = np.empty(size)
    entries = nonzero_entries(general)
    _rows_in_basis(entries, basis, point, lower, upper, rows, lower_out, upper_out)
    return rows, lower_out, upper_out
