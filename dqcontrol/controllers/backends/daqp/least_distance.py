"""A block-diagonal QP as a least-distance problem, for DAQP (the predictive step's solve).

The predictive controllers' Hessian is block diagonal (one ``(n+1)``-square block per
instant), but DAQP factorises and inverts the dense ``H`` whenever it changes, a cost
cubic in the number of variables whatever the constraints. With the Cholesky factors of
the blocks, ``H = L Lᵀ`` (L block diagonal, a few hundred flops), the change of variables
``u = Lᵀ z + L⁻¹ c`` turns

    minimize ½ zᵀ H z + cᵀ z   s.t.  lower ≤ A z ≤ upper

into the least-distance problem

    minimize ½ ‖u‖²   s.t.  lower + A w ≤ M u ≤ upper + A w,   M = A L⁻ᵀ,  w = L⁻ᵀ L⁻¹ c

with ``z = L⁻ᵀ u - w``. DAQP then keeps ``H = I`` for good and gets a new ``M`` and new
bounds at every step, which costs it a fraction of a refactorisation (docs/theory.md §6).
:func:`block_ldp` builds ``M``, the bounds and the factors in one compiled call, exploiting
the blocks and the sparsity of ``A = [I; A_general]``; :func:`ldp_solution` maps ``u`` back.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

from dqcontrol._compiled import compiled

__all__ = ["block_ldp", "dense_ldp", "ldp_solution"]


@compiled
def _factor_block(
    h: np.ndarray, o: int, block: int, factor: np.ndarray, inv: np.ndarray, linv_t: np.ndarray
) -> bool:
    """Cholesky factor ``L`` of the block of ``h`` at offset ``o``, its inverse in ``inv``
    and ``L⁻ᵀ`` in ``linv_t`` (block, block); False when the block is not safely positive
    definite (a squared pivot ≤ 1e-12 times its largest diagonal entry, or NaN)."""
    scale = 0.0
    for i in range(block):
        scale = max(scale, h[o + i, o + i])
    for i in range(block):
        for j in range(i + 1):
            s = h[o + i, o + j]
            for k in range(j):
                s -= factor[i, k] * factor[j, k]
            if i == j:
                if not s > 1e-12 * scale:
                    return False
                factor[i, i] = math.sqrt(s)
            else:
                factor[i, j] = s / factor[j, j]
    # the inverse (lower triangular), column by column
    for j in range(block):
        for i in range(j):
            inv[i, j] = 0.0
        inv[j, j] = 1.0 / factor[j, j]
        for i in range(j + 1, block):
            s = 0.0
            for k in range(j, i):
                s -= factor[i, k] * inv[k, j]
            inv[i, j] = s / factor[i, i]
    for i in range(block):
        for j in range(block):
            linv_t[i, j] = inv[j, i]
    return True


@compiled
def _shift_block(
    inv: np.ndarray, c: np.ndarray, o: int, block: int, g: np.ndarray, w: np.ndarray
) -> None:
    """``w = L⁻ᵀ (L⁻¹ c)`` on the block at offset ``o`` (``inv`` = ``L⁻¹``)."""
    for i in range(block):
        s = 0.0
        for k in range(i + 1):
            s += inv[i, k] * c[o + k]
        g[i] = s
    for i in range(block):
        s = 0.0
        for k in range(i, block):
            s += inv[k, i] * g[k]
        w[o + i] = s


@compiled
def _distance_rows(
    block: int,
    lower: np.ndarray,
    upper: np.ndarray,
    a_ptr: np.ndarray,
    a_idx: np.ndarray,
    a_val: np.ndarray,
    linv_t: np.ndarray,
    w: np.ndarray,
    m_out: np.ndarray,
    lo_out: np.ndarray,
    up_out: np.ndarray,
) -> None:
    """``M = A L⁻ᵀ`` and the bounds shifted by ``A w`` (clamped to ±1e30): the identity rows
    give the blocks of ``L⁻ᵀ``, a general row the combination of the rows of ``L⁻ᵀ`` its
    entries name."""
    n = w.shape[0]
    m_out[:, :] = 0.0
    for r in range(n):
        b, i = r // block, r % block
        o = b * block
        for j in range(block):
            m_out[r, o + j] = linv_t[b, i, j]
        lo_out[r] = max(lower[r] + w[r], -1e30)
        up_out[r] = min(upper[r] + w[r], 1e30)
    for r in range(a_ptr.shape[0] - 1):
        row = n + r
        shift = 0.0
        for e in range(a_ptr[r], a_ptr[r + 1]):
            col, val = a_idx[e], a_val[e]
            b, i = col // block, col % block
            o = b * block
            for j in range(block):
                m_out[row, o + j] += val * linv_t[b, i, j]
            shift += val * w[col]
        lo_out[row] = max(lower[row] + shift, -1e30)
        up_out[row] = min(upper[row] + shift, 1e30)


@compiled
def block_ldp(
    h: np.ndarray,
    block: int,
    c: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    a_ptr: np.ndarray,
    a_idx: np.ndarray,
    a_val: np.ndarray,
    m_out: np.ndarray,
    lo_out: np.ndarray,
    up_out: np.ndarray,
    linv_t: np.ndarray,
    w: np.ndarray,
) -> bool:
    """Fill the least-distance problem of ``(h, c, A = [I; A_general], lower, upper)``.

    ``h`` (N, N) is block diagonal with ``block``-square blocks; ``A_general`` is given by
    rows in CSR form (``a_ptr``, ``a_idx``, ``a_val``). Writes ``M`` to ``m_out``
    (N + rows, N), the shifted bounds (clamped to ±1e30) to ``lo_out``/``up_out``, each
    block's ``L⁻ᵀ`` to ``linv_t`` (N/block, block, block) and ``w = L⁻ᵀ L⁻¹ c`` to ``w``.
    Returns False, with the outputs partly written, when a block is not safely positive
    definite (a squared pivot ≤ 1e-12 times the block's largest diagonal entry, or NaN: a
    condition number beyond ~1e12 would make ``M`` lose digits): the caller then solves the
    problem as it is.
    """
    n = h.shape[0]
    factor = np.empty((block, block))
    inv = np.empty((block, block))
    g = np.empty(block)
    for b in range(n // block):
        o = b * block
        if not _factor_block(h, o, block, factor, inv, linv_t[b]):
            return False
        _shift_block(inv, c, o, block, g, w)
    _distance_rows(block, lower, upper, a_ptr, a_idx, a_val, linv_t, w, m_out, lo_out, up_out)
    return True


def dense_ldp(
    factor: np.ndarray,
    c: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    general: np.ndarray,
    m_out: np.ndarray,
    lo_out: np.ndarray,
    up_out: np.ndarray,
    linv_t: np.ndarray,
    w: np.ndarray,
) -> bool:
    """:func:`block_ldp` for a dense ``h = L Lᵀ`` (N, N), one block, given its lower
    Cholesky factor ``factor``, with the general rows given dense (``general`` (rows, N);
    their zero entries are skipped).

    Writes ``M = [L⁻ᵀ; general L⁻ᵀ]`` to ``m_out`` (N + rows, N), the shifted bounds to
    ``lo_out``/``up_out``, ``L⁻ᵀ`` to ``linv_t`` (1, N, N) and ``w`` to ``w``; returns False
    when LAPACK cannot invert the factor. The inverse comes from LAPACK (``trtri``; call it
    with one BLAS thread, :func:`~dqcontrol._blas.single_blas_thread`), the rest from one
    compiled pass.
    """
    inverse, info = lapack.dtrtri(factor, lower=1)
    if info != 0:
        return False
    linv_t[0] = inverse.T
    _dense_rows(linv_t[0], c, lower, upper, general, m_out, lo_out, up_out, w)
    return True


@compiled
def _dense_rows(
    lt: np.ndarray,
    c: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    general: np.ndarray,
    m_out: np.ndarray,
    lo_out: np.ndarray,
    up_out: np.ndarray,
    w: np.ndarray,
) -> None:
    """``w = L⁻ᵀ L⁻¹ c``, ``M = [L⁻ᵀ; general L⁻ᵀ]`` and the shifted bounds (clamped to
    ±1e30) from ``lt = L⁻ᵀ`` (upper triangular)."""
    n = lt.shape[0]
    g = np.zeros(n)  # L⁻¹ c = (L⁻ᵀ)ᵀ c
    for i in range(n):
        ci = c[i]
        for j in range(i, n):
            g[j] += ci * lt[i, j]
    for i in range(n):
        acc = 0.0
        for j in range(i, n):
            acc += lt[i, j] * g[j]
        w[i] = acc
    for r in range(n):
        for j in range(n):
            m_out[r, j] = lt[r, j]
        lo_out[r] = max(lower[r] + w[r], -1e30)
        up_out[r] = min(upper[r] + w[r], 1e30)
    for r in range(general.shape[0]):
        row = n + r
        for j in range(n):
            m_out[row, j] = 0.0
        shift = 0.0
        for col in range(n):
            val = general[r, col]
            if val == 0.0:
                continue
            for j in range(col, n):  # L⁻ᵀ is upper triangular
                m_out[row, j] += val * lt[col, j]
            shift += val * w[col]
        lo_out[row] = max(lower[row] + shift, -1e30)
        up_out[row] = min(upper[row] + shift, 1e30)


@compiled
def ldp_solution(linv_t: np.ndarray, u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``z = L⁻ᵀ u - w`` (new array) from the least-distance solution ``u``."""
    block = linv_t.shape[1]
    z = np.empty(u.shape[0])
    for b in range(linv_t.shape[0]):
        o = b * block
        for i in range(block):
            s = 0.0
            for j in range(block):
                s += linv_t[b, i, j] * u[o + j]
            z[o + i] = s - w[o + i]
    return z
