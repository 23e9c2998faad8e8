"""A level's objective and rows in the null space of the levels above (docs/theory.md §7.4).

With ``z = z₀ + Z y``, a residual's rows ``A z - b`` become ``(A Z) y + (A z₀ - b)``: the
reduced level's Hessian and gradient are sums over the rows of ``A Z`` and ``A z₀ - b``
(each residual's ``2 w`` and row weights), never the ``n × n`` Hessian of the whole
level. ``A Z`` is computed from the residual's own form: per block for block-diagonal rows,
skipping zeros for sparse rows. The general rows of the limits ``C Z`` skip ``C``'s zeros
too (the coupling of neighbouring intervals, a trust region: a few entries per row); a
read-only ``C`` gives its non-zero entries once (:func:`~dqcontrol.controllers.gram.kept`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.gram import kept
from dqcontrol.controllers.problem import Residual

__all__ = [
    "ReducedObjective",
    "nonzero_entries",
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
def _block_rows(
    blocks: np.ndarray,
    basis: np.ndarray,
    point: np.ndarray,
    b: np.ndarray,
    w2: float,
    row_weights: np.ndarray,
    out: np.ndarray,
    scale: np.ndarray,
) -> None:
    """``out = [A basis | A point - b]`` for ``A = blockdiag(blocks)`` (``blocks``
    ``(p, r, m)``, ``basis`` at least ``p m`` rows) skipping the blocks' zeros, and the
    rows' scales."""
    p, r, m = blocks.shape
    out[:] = 0.0
    for i in range(p):
        for a in range(r):
            row = i * r + a
            for k in range(m):
                v = blocks[i, a, k]
                if v != 0.0:
                    _add_row(out[row], v, basis, point, i * m + k)
            _finish_row(out, row, b, w2, row_weights, scale)


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


@compiled
def _nonzero_entries(a: np.ndarray) -> np.ndarray:
    count = 0
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            count += a[i, j] != 0.0
    out = np.empty((count, 3))
    e = 0
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            if a[i, j] != 0.0:
                out[e, 0] = i
                out[e, 1] = j
                out[e, 2] = a[i, j]
                e += 1
    return out


def nonzero_entries(a: np.ndarray) -> np.ndarray:
    """The non-zero entries of ``a`` row by row, ``(nnz, 3)``: row, column, value (the
    indices exact as floats); computed once for a read-only ``a``."""
    return kept((a,), _nonzero_entries)


def sparse_product(a: np.ndarray, right: np.ndarray) -> np.ndarray:
    """``a @ right`` (``right`` 2-D) skipping the zeros of ``a``: each entry of the result
    sums its non-zero products in column order."""
    out = np.empty((a.shape[0], right.shape[1]))
    _entry_product(nonzero_entries(a), right, out)
    return out


_NO_WEIGHTS = np.zeros(0)


def _residual_rows(
    r: Residual, basis: np.ndarray, point: np.ndarray, out: np.ndarray, scale: np.ndarray
) -> None:
    """``out = [A basis | A point - b]`` for the residual's rows ``A``, and each row's
    ``2 w`` times its weight in ``scale``."""
    weights = _NO_WEIGHTS if r.row_weights is None else r.row_weights
    if r.blocks is not None:
        _block_rows(r.blocks, basis, point, r.b, 2.0 * r.weight, weights, out, scale)
    else:
        assert r.A is not None, "a residual has A or blocks"
        _entry_rows(nonzero_entries(r.A), basis, point, r.b, 2.0 * r.weight, weights, out, scale)


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


def reduced_objective(
    residuals: tuple[Residual, ...], point: np.ndarray, basis: np.ndarray
) -> ReducedObjective:
    """``Σ w ‖A (point + basis y) - b‖²`` as ``½ yᵀ H y + gᵀ y`` up to a constant, and
    the held rows ``A basis`` of the held residuals stacked in order."""
    held = [r for r in residuals if r.held]
    used = held + [r for r in residuals if not r.held and 2.0 * r.weight != 0.0]
    total = sum(r.b.size for r in used)
    rows = np.empty((total, basis.shape[1] + 1))  # [A basis | A point - b] of every one
    scale = np.empty(total)  # 2 w times the row's weight
    start = 0
    for r in used:
        end = start + r.b.size
        _residual_rows(r, basis, point, rows[start:end], scale[start:end])
        start = end
    hessian, gradient = _weighted_gram(rows, scale)
    return ReducedObjective(hessian, gradient, rows[: sum(r.b.size for r in held), :-1])


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
