"""Householder QR factorisations, compiled, for the null spaces of the levels' rows
(docs/theory.md §7.4).

The reflectors are LAPACK's (``v[0] = 1`` implied, the rest stored below the diagonal,
``β`` on it, ``H = I - τ v vᵀ``), so that ``Q`` is the one LAPACK's ``dgeqrf``/``dgeqp3``
give up to rounding. :func:`profile_qr` lets each vector reach only the rows it must (rows
of a level that reach part of the variables), :func:`pivoted_qr` pivots the columns (the
rank), :func:`applied_q` gives columns of ``Q``.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["applied_q", "pivoted_qr", "profile_qr"]


@compiled
def _reflect(
    mat: np.ndarray, top: int, start: int, vector: np.ndarray, tau: float, w: np.ndarray
) -> None:
    """``B -= tau v (vᵀ B)`` for the block ``B`` of ``mat`` from row ``top`` and column
    ``start`` over ``vector.size + 1`` rows, ``v = [1; vector]`` (``w``: a buffer as long as
    a row). The inner loops run along rows of the C-ordered ``mat``, from 0: the form the
    compiler vectorises."""
    size = mat.shape[1] - start
    first = mat[top, start:]
    for k in range(size):
        w[k] = first[k]
    for i in range(vector.size):
        v = vector[i]
        row = mat[top + 1 + i, start:]
        for k in range(size):
            w[k] += v * row[k]
    for k in range(size):
        first[k] -= tau * w[k]
    for i in range(vector.size):
        v = tau * vector[i]
        row = mat[top + 1 + i, start:]
        for k in range(size):
            row[k] -= v * w[k]


@compiled
def _householder(columns: np.ndarray, j: int, end: int, vector: np.ndarray, w: np.ndarray) -> tuple:
    """The reflector of column ``j`` over rows ``j … end - 1`` (LAPACK's: ``v[0] = 1``
    implied, the rest stored below the diagonal, ``β`` on it), applied to the columns
    after ``j``; returns ``(tau, pivot)``."""
    alpha = columns[j, j]
    tail = 0.0
    for i in range(j + 1, end):
        tail += columns[i, j] * columns[i, j]
    if tail == 0.0:
        return 0.0, alpha
    beta = -math.copysign(math.sqrt(alpha * alpha + tail), alpha)
    tau = (beta - alpha) / beta
    scale = 1.0 / (alpha - beta)
    for i in range(j + 1, end):
        columns[i, j] *= scale
        vector[i - j - 1] = columns[i, j]
    columns[j, j] = beta
    if j + 1 < columns.shape[1]:
        _reflect(columns, j, j + 1, vector[: end - j - 1], tau, w)
    return tau, beta


@compiled
def profile_qr(columns: np.ndarray, reach: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Householder QR of ``columns`` ``(n, r)`` in place, each vector ``j`` over rows
    ``j … reach[j]``. Returns ``tau`` and the diagonal of ``R``."""
    r = columns.shape[1]
    tau = np.zeros(r)
    pivots = np.empty(r)
    w = np.empty(r)
    vector = np.empty(columns.shape[0])
    for j in range(r):
        tau[j], pivots[j] = _householder(columns, j, reach[j] + 1, vector, w)
    return tau, pivots


@compiled
def pivoted_qr(columns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Householder QR of ``columns`` ``(n, r)`` in place with column pivoting: step ``j``
    takes the first remaining column of largest norm below row ``j``. Returns ``tau`` and
    the diagonal of ``R`` (``min(n, r)`` each)."""
    n, r = columns.shape
    k = min(n, r)
    tau = np.zeros(k)
    pivots = np.empty(k)
    w = np.empty(r)
    vector = np.empty(n)
    for j in range(k):
        best = -1.0
        chosen = j
        for c in range(j, r):
            norm = 0.0
            for i in range(j, n):
                norm += columns[i, c] * columns[i, c]
            if norm > best:
                best = norm
                chosen = c
        if chosen != j:
            for i in range(n):
                columns[i, j], columns[i, chosen] = columns[i, chosen], columns[i, j]
        tau[j], pivots[j] = _householder(columns, j, n, vector, w)
    return tau, pivots


@compiled
def applied_q(columns: np.ndarray, reach: np.ndarray, tau: np.ndarray, first: int) -> np.ndarray:
    """The columns from ``first`` on of ``Q`` of the factorisation in ``columns`` (the
    reflectors of :func:`profile_qr` or :func:`pivoted_qr`, vector ``j`` reaching row
    ``reach[j]``)."""
    n = columns.shape[0]
    m = n - first
    basis = np.zeros((n, m))
    for c in range(m):
        basis[first + c, c] = 1.0
    w = np.empty(m)
    vector = np.empty(n)
    for j in range(tau.size - 1, -1, -1):
        if tau[j] == 0.0:
            continue
        end = reach[j] + 1
        for i in range(j + 1, end):
            vector[i - j - 1] = columns[i, j]
        _reflect(basis, j, 0, vector[: end - j - 1], tau[j], w)
    return basis
