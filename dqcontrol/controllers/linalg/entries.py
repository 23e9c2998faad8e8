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
from dqcontrol.controllers.linalg.gram import frozen, kept

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


@compiled
def _stacked(blocks: tuple, rows: np.ndarray) -> np.ndarray:
    """The entries ``blocks`` one below the other, block ``k``'s rows moved down by the
    ``rows`` of the blocks before it."""
    total = 0
    for k in range(len(blocks)):
        total += blocks[k].shape[0]
    out = np.empty((total, 3))
    e, offset = 0, 0.0
    for k in range(len(blocks)):
        block = blocks[k]
        for i in range(block.shape[0]):
            out[e, 0] = block[i, 0] + offset
            out[e, 1] = block[i, 1]
            out[e, 2] = block[i, 2]
            e += 1
        offset += rows[k]
    return out


def _each(*parts: np.ndarray) -> np.ndarray:
    """The entries of ``parts`` one below the other, from each part's own."""
    blocks = tuple(nonzero_entries(part) for part in parts)
    return _stacked(blocks, np.array([part.shape[0] for part in parts], dtype=float))


def _stack(*parts: np.ndarray) -> np.ndarray:
    """The entries of ``parts`` one below the other, each part's rows after the last's:
    each run of read-only parts from its own kept entries (one lookup for the run)."""
    blocks, rows, run = [], [], []
    for part in (*parts, None):
        if part is not None and not part.flags.writeable:
            run.append(part)
            continue
        if run:
            blocks.append(nonzero_entries(run[0]) if len(run) == 1 else kept(tuple(run), _each))
            rows.append(sum(r.shape[0] for r in run))
            run = []
        if part is not None:
            blocks.append(nonzero_entries(part))
            rows.append(part.shape[0])
    return _stacked(tuple(blocks), np.array(rows, dtype=float))


def stacked_entries(parts: tuple[np.ndarray, ...]) -> np.ndarray:
    """:func:`nonzero_entries` of the rows ``parts`` stacked, from each part's own: kept
    whole while every part is read-only; otherwise each run of read-only parts kept as
    one, and only the writable parts' scanned."""
    if not parts:
        return _NO_ENTRIES
    return frozen(
        kept(parts, _each) if all(not p.flags.writeable for p in parts) else _stack(*parts)
    )
