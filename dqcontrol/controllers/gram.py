"""Products of constant rows, computed once: the Gram matrices of a level's objective and
the stacked rows of a problem.

:func:`~dqcontrol.controllers.problem.objective` adds ``2 w AᵀA`` of every residual to the
Hessian at every step. Rows that never change (a damping's identity blocks, a smoothness
term's differences, a limit's constant matrix) give the same products at every step: a term
or limit marks such an array read-only (:func:`frozen`), and a product of read-only arrays
is then computed once, by the same numpy expression as for changing arrays (the same
numbers, bit for bit), and kept while its operands live (:func:`kept`).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["add_diagonal_blocks", "block_gram", "block_lin", "dense_gram", "frozen", "kept"]

#: How many products are kept at most (a few per controller).
_CAPACITY = 256
#: ``(the function, ids of the operands) -> (weak references to them, the product)``.
_KEPT: dict[tuple, tuple[tuple[weakref.ref, ...], np.ndarray]] = {}


def frozen(array: np.ndarray) -> np.ndarray:
    """``array`` marked read-only (products of it may be kept); returns it."""
    array.flags.writeable = False
    return array


def kept(operands: tuple[np.ndarray, ...], compute: Callable[..., np.ndarray]) -> np.ndarray:
    """``compute(*operands)``, kept while every operand lives when all are read-only."""
    if any(a.flags.writeable for a in operands):
        return compute(*operands)
    key = (compute, *(id(a) for a in operands))
    entry = _KEPT.get(key)
    if entry is not None and all(r() is a for r, a in zip(entry[0], operands, strict=True)):
        return entry[1]
    if len(_KEPT) >= _CAPACITY:  # the oldest entries go first
        for old in list(_KEPT)[: _CAPACITY // 2]:
            del _KEPT[old]
    value = frozen(compute(*operands))
    _KEPT[key] = (tuple(weakref.ref(a) for a in operands), value)
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
