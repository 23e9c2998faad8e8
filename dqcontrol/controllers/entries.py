"""A matrix as its non-zero entries (docs/theory.md §7.5).

The general rows ``C`` of a problem are sparse (a limit's row reaches the commands up to
its instant, or one joint): the active-set kernels read them as their non-zero entries,
row by row, columns in order (``(nnz, 3)``: row, column, value, the indices exact as
floats), so that each sum over a row runs over its non-zero terms only, in the order the
dense sum would take them.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.gram import frozen, kept

__all__ = ["nonzero_entries", "stacked_entries"]

_NO_ENTRIES = frozen(np.zeros((0, 3)))


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
    """The non-zero entries of ``a`` row by row, ``(nnz, 3)``: row, column, value;
    computed once for a read-only ``a``. Always read-only, so that the kernels reading
    them are compiled for one form."""
    return frozen(kept((a,), _nonzero_entries))


def _stack(*parts: np.ndarray) -> np.ndarray:
    """The entries of ``parts`` one below the other, each part's rows after the last's."""
    blocks = [nonzero_entries(part) for part in parts]
    out = np.concatenate(blocks)
    start, row = 0, 0
    for part, block in zip(parts, blocks, strict=True):
        out[start : start + block.shape[0], 0] += row
        start += block.shape[0]
        row += part.shape[0]
    return out


def stacked_entries(parts: tuple[np.ndarray, ...]) -> np.ndarray:
    """:func:`nonzero_entries` of the rows ``parts`` stacked, from each part's own (kept
    while every part is read-only; a read-only part's own are kept while it lives)."""
    if not parts:
        return _NO_ENTRIES
    return frozen(kept(parts, _stack))
