"""Products of constant rows, computed once: the Gram matrices of a level's objective and
the stacked rows of a problem.

:func:`~dqcontrol.controllers.core.problem.objective` adds ``2 w AᵀA`` of every residual to the
Hessian at every step. Rows that never change (a damping's identity blocks, a smoothness
term's differences, a limit's constant matrix) give the same products at every step: a term
or limit marks such an array read-only (:func:`frozen`), and a product of read-only arrays
is then computed once, by the same numpy expression as for changing arrays (the same
numbers, bit for bit), and kept with its operands (:func:`kept`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dqcontrol._compiled import compiled

__all__ = [
    "add_diagonal_blocks",
    "add_scaled",
    "block_gram",
    "block_lin",
    "dense_gram",
    "frozen",
    "kept",
    "selector_rows",
    "subtract_block_lin",
    "subtract_scaled",
]

#: How many products are kept at most (a few per controller).
_CAPACITY = 256
#: ``(the function, ids of the operands) -> (the operands, the product)``. An entry holds
#: its operands, so that no other array takes their ids while it is kept.
_KEPT: dict[tuple, tuple[tuple[np.ndarray, ...], np.ndarray]] = {}


def frozen(array: np.ndarray) -> np.ndarray:
    """``array`` marked read-only (products of it may be kept); returns it."""
    array.flags.writeable = False
    return array


def kept(
    operands: tuple[np.ndarray, ...], compute: Callable[..., np.ndarray], params: tuple = ()
) -> np.ndarray:
    """``compute(*operands, *params)``, kept when every operand is read-only (``params``:
    hashable values the result also depends on, part of the key; at most
    :data:`_CAPACITY` results, the oldest forgotten first)."""
    for a in operands:
        if a.flags.writeable:
            return compute(*operands, *params)
    if len(operands) == 1:  # the common case, without the general loops
        key: tuple = (compute, params, id(operands[0]))
    else:
        key = (compute, params, *map(id, operands))
    entry = _KEPT.get(key)
    if entry is not None:  # the entry holds its operands: their ids name no other array
        return entry[1]
    if len(_KEPT) >= _CAPACITY:  # the oldest entries go first
        for old in list(_KEPT)[: _CAPACITY // 2]:
            del _KEPT[old]
    value = frozen(compute(*operands, *params))
    _KEPT[key] = (operands, value)
    return value


def _block_gram(blocks: np.ndarray) -> np.ndarray:
    return np.matmul(blocks.transpose(0, 2, 1), blocks)


def _block_lin(blocks: np.ndarray, b: np.ndarray) -> np.ndarray:
    p = blocks.shape[0]
    return np.matmul(blocks.transpose(0, 2, 1), b.reshape(p, -1, 1))[:, :, 0].ravel()


def _dense_gram(a: np.ndarray) -> np.ndarray:
    return a.T @ a


def block_gram(blocks: np.ndarray) -> np.ndarray:
    """``A_iᵀ A_i`` of every block ``(p, m, m)`` of ``blocks`` ``(p, r, m)``."""
    return kept((blocks,), _block_gram)


def block_lin(blocks: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A_iᵀ b_i`` of every block, flat ``(p m,)`` (``b`` is ``(p r,)``)."""
    return kept((blocks, b), _block_lin)


def dense_gram(a: np.ndarray) -> np.ndarray:
    """``AᵀA`` ``(k, k)`` of rows ``a`` ``(r, k)``."""
    return kept((a,), _dense_gram)


@compiled
def add_diagonal_blocks(hessian: np.ndarray, gram: np.ndarray, w2: float) -> None:
    """``hessian[block i, block i] += w2 gram[i]`` in place for every block ``i`` of
    ``gram`` ``(p, m, m)`` (``hessian`` is ``(p m, p m)``): the product rounded, then
    the sum, as numpy's ``+= w2 * gram``."""
    p, m = gram.shape[0], gram.shape[1]
    for i in range(p):
        o = i * m
        for a in range(m):
            for b in range(m):
                hessian[o + a, o + b] += w2 * gram[i, a, b]


@compiled
def add_scaled(out: np.ndarray, values: np.ndarray, w2: float) -> None:
    """``out += w2 values`` in place (2-D): the product rounded, then the sum, as numpy's
    ``out += w2 * values``."""
    if values.shape[0] != out.shape[0] or values.shape[1] != out.shape[1]:
        raise ValueError("add_scaled: values and out differ in shape")
    for a in range(out.shape[0]):
        for b in range(out.shape[1]):
            out[a, b] += w2 * values[a, b]


@compiled
def subtract_scaled(out: np.ndarray, values: np.ndarray, w2: float) -> None:
    """``out[:len(values)] -= w2 values`` in place (1-D), as numpy's ``out -= w2 *
    values`` on those entries (block rows may cover only the first blocks of ``z``)."""
    if values.shape[0] > out.shape[0]:
        raise ValueError("subtract_scaled: values longer than out")
    for a in range(values.shape[0]):
        out[a] -= w2 * values[a]


def _selector_rows(blocks: np.ndarray) -> np.ndarray:
    """Per block and column the one row with a non-zero entry (``-1``: none) ``(p, m)``;
    empty where some column has more than one."""
    nonzero = blocks != 0.0
    if np.any(nonzero.sum(axis=1) > 1):
        return np.zeros(0, dtype=np.int64)
    return np.where(nonzero.any(axis=1), nonzero.argmax(axis=1), -1).astype(np.int64)


def selector_rows(blocks: np.ndarray) -> np.ndarray:
    """:func:`_selector_rows` of read-only ``blocks`` (kept), empty for writable ones."""
    if blocks.flags.writeable:
        return np.zeros(0, dtype=np.int64)
    return kept((blocks,), _selector_rows)


@compiled
def _subtract_selected(
    c: np.ndarray, blocks: np.ndarray, rows: np.ndarray, b: np.ndarray, w2: float
) -> None:
    """``c -= w2 A_iᵀ b_i`` for blocks with one non-zero entry per column at most:
    ``rows[i, k]`` (``-1``: none)."""
    p, r, m = blocks.shape
    for i in range(p):
        for k in range(m):
            j = rows[i, k]
            if j >= 0:
                c[i * m + k] -= w2 * (blocks[i, j, k] * b[i * r + j])


def subtract_block_lin(c: np.ndarray, blocks: np.ndarray, b: np.ndarray, w2: float) -> None:
    """``c -= w2 A_iᵀ b_i`` of every block in place, as ``c -= w2 * block_lin(blocks, b)``.

    Where each column of a read-only block has one non-zero entry at most (a selection of
    variables, a scaled one), each sum of ``A_iᵀ b_i`` has one non-zero product: exact
    whatever the order of the sum, so one compiled pass gives the same numbers."""
    rows = selector_rows(blocks)
    if rows.size:
        _subtract_selected(c, blocks, rows, b, w2)
    else:
        subtract_scaled(c, block_lin(blocks, b), w2)
