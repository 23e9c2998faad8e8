"""The first level's dense objective with each changing dense residual in one compiled call
(docs/theory.md §7.4).

:func:`~dqcontrol.controllers.problem.objective` adds a residual with changing dense rows
(a path level's error rows, row-weighted) through several numpy operations: the weighted
rows, their product, its scaled sum into the Hessian, the linear term. Here one compiled
call does the same sums in the same order (:func:`level_objective`); block-diagonal
residuals go through the same kernels as there. A level whose live rows are all read-only
(``P`` is then kept), or that has other forms, is left to
:func:`~dqcontrol.controllers.problem.objective`.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.gram import add_diagonal_blocks, block_gram, frozen, subtract_block_lin
from dqcontrol.controllers.problem import DecisionLayout, Residual, objective

__all__ = ["level_objective"]

_NO_WEIGHTS = frozen(np.zeros(0))  # read-only as row weights are: one compiled form


@compiled
def _add_changing_rows(
    p_mat: np.ndarray,
    c: np.ndarray,
    a: np.ndarray,
    row_weights: np.ndarray,
    b: np.ndarray,
    w2: float,
) -> None:
    """``p_mat += w2 (W A)ᵀ A`` and ``c -= w2 (W A)ᵀ b`` in place (``row_weights`` empty:
    ``W = I``), each product rounded before its sum as numpy's ``+= w2 * …``."""
    weighted = np.empty_like(a)
    for i in range(a.shape[0]):
        scale = row_weights[i] if row_weights.size else 1.0
        for j in range(a.shape[1]):
            weighted[i, j] = a[i, j] * scale
    gram = weighted.T @ a
    for i in range(gram.shape[0]):
        for j in range(gram.shape[1]):
            p_mat[i, j] += w2 * gram[i, j]
    lin = weighted.T @ b
    for i in range(c.size):
        c[i] -= w2 * lin[i]


def _changing_dense(r: Residual) -> bool:
    """Whether ``r`` has dense rows that change (writable)."""
    return r.A is not None and r.A.flags.writeable


def level_objective(layout: DecisionLayout, residuals: tuple[Residual, ...]) -> tuple:
    """``(P, c)`` of :func:`~dqcontrol.controllers.problem.objective`: the same sums in the
    same order, each changing dense residual in one compiled call."""
    live = tuple(r for r in residuals if 2.0 * r.weight != 0.0)
    if not any(_changing_dense(r) for r in live) or not all(
        r.blocks is not None or _changing_dense(r) for r in live
    ):
        return objective(layout, residuals)
    nv = layout.num_vars
    p_mat = np.zeros((nv, nv))
    c = np.zeros(nv)
    for r in live:
        w2 = 2.0 * r.weight
        if r.blocks is not None:
            add_diagonal_blocks(p_mat, block_gram(r.blocks), w2)
            subtract_block_lin(c, r.blocks, r.b, w2)
        else:
            weights = _NO_WEIGHTS if r.row_weights is None else r.row_weights
            _add_changing_rows(p_mat, c, np.ascontiguousarray(r.A), weights, r.b, w2)
    return p_mat, c
