"""The null space of the rows a level holds (docs/theory.md §7.4).

An orthonormal basis of ``{y : R y = 0}`` from a QR factorisation of ``Rᵀ`` (LAPACK):
without pivoting (``dgeqrf``, and ``dormqr`` applies ``Q`` to the last columns of the
identity) where every pivot is clearly non-zero, which is the usual case; otherwise with
column pivoting (``dgeqp3``/``dorgqr``), which reveals the rank, so that dependent rows (a
level whose rows repeat each other) cost nothing and break nothing.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

__all__ = ["RANK_TOLERANCE", "null_space"]

#: A pivot of the QR below this share of the largest one counts as zero.
RANK_TOLERANCE = 1e-10
#: Without pivoting, the smallest pivot must be at least this share of the largest.
_FULL_RANK_SHARE = 1e-8


def null_space(rows: np.ndarray) -> np.ndarray:
    """An orthonormal basis ``(n, n - rank)`` of the null space of ``rows`` ``(r, n)``."""
    r, n = rows.shape
    if r == 0:
        return np.eye(n)
    if r < n:
        basis = _full_rank_complement(rows)
        if basis is not None:
            return basis
    return _pivoted(rows)


def _full_rank_complement(rows: np.ndarray) -> np.ndarray | None:
    """The basis when the ``r < n`` rows are clearly independent, else ``None``."""
    r, n = rows.shape
    qr, tau, _work, info = lapack.dgeqrf(np.array(rows.T, order="F"))
    if info != 0:
        return None
    pivots = np.abs(np.diagonal(qr))
    if not float(pivots.min()) >= _FULL_RANK_SHARE * float(pivots.max()) > 0.0:
        return None
    tail = np.zeros((n, n - r), order="F")
    tail[r:] = np.eye(n - r)
    basis, _work, info = lapack.dormqr("L", "N", qr, tau, tail, max(1, 64 * (n - r)))
    return None if info != 0 else np.ascontiguousarray(basis)


def _pivoted(rows: np.ndarray) -> np.ndarray:
    """The basis from a QR with column pivoting (rank-revealing)."""
    r, n = rows.shape
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
