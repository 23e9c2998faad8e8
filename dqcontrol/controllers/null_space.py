"""The null space of the rows a level holds (docs/theory.md §7.4).

An orthonormal basis of ``{y : R y = 0}`` by a QR factorisation with column pivoting of
``Rᵀ`` (LAPACK ``dgeqp3``/``dorgqr``): rank-revealing, so dependent rows (a level whose
rows repeat each other) cost nothing and break nothing.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

__all__ = ["RANK_TOLERANCE", "null_space"]

#: A pivot of the QR below this share of the largest one counts as zero.
RANK_TOLERANCE = 1e-10


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
