"""Null spaces and products for the lexicographic solve (docs/theory.md §7.4).

``null_space`` gives an orthonormal basis of ``{y : R y = 0}`` by a QR factorisation with
column pivoting of ``Rᵀ`` (LAPACK ``dgeqp3``/``dorgqr``): rank-revealing, so dependent rows
(a level whose rows repeat each other) cost nothing and break nothing. ``product`` is a
matrix product split by rows so that each part stays below OpenBLAS's threshold for
threading (``m n k ≤ 2.6e5``): a control step must not wait for a second BLAS thread on a
busy machine.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

__all__ = ["RANK_TOLERANCE", "null_space", "product"]

#: A pivot of the QR below this share of the largest one counts as zero.
RANK_TOLERANCE = 1e-10
#: Largest ``m n k`` of one product part (OpenBLAS threads a product above 65536 × 4).
_SINGLE_THREAD_WORK = 250_000


def null_space(rows: np.ndarray) -> np.ndarray:
    """An orthonormal basis ``(n, n - rank)`` of the null space of ``rows`` ``(r, n)``."""
    r, n = rows.shape
    if r == 0:
        return np.eye(n)
    qr, _pivots, tau, _work, info = lapack.dgeqp3(np.array(rows.T, order="F"))
    if info != 0:
        raise np.linalg.LinAlgError(f"dgeqp3 failed (info {info})")
    k = min(n, r)
    diagonal = np.abs(np.diagonal(qr)[:k])
    largest = float(diagonal[0]) if k else 0.0
    rank = int(np.count_nonzero(diagonal > RANK_TOLERANCE * largest)) if largest > 0 else 0
    if rank == n:
        return np.zeros((n, 0))
    reflectors = np.zeros((n, n), order="F")
    reflectors[:, :k] = qr[:, :k]
    q, _work, info = lapack.dorgqr(reflectors, tau[:k])
    if info != 0:
        raise np.linalg.LinAlgError(f"dorgqr failed (info {info})")
    return np.ascontiguousarray(q[:, rank:])


def product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b``, computed in row blocks small enough for one BLAS thread."""
    m, k = a.shape
    n = b.shape[1] if b.ndim == 2 else 1
    rows = max(1, _SINGLE_THREAD_WORK // max(1, k * n))
    if m <= rows:
        return a @ b
    return np.concatenate([a[i : i + rows] @ b for i in range(0, m, rows)])
