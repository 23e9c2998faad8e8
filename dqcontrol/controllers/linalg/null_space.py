"""The null space of the rows a level holds (docs/theory.md §7.4).

An orthonormal basis of ``{y : R y = 0}`` from a QR factorisation of ``Rᵀ``: without
pivoting where every pivot is clearly non-zero, which is the usual case; otherwise with
column pivoting, which reveals the rank, so that dependent rows (a level whose rows repeat
each other) cost nothing and break nothing (compiled for the small ``R Z`` of a narrowed
level, LAPACK's ``dgeqp3``/``dorgqr`` for large rows).

Without pivoting, the basis is ``Q`` applied to the last columns of the identity. Where
the rows reach fewer variables than all (a row of a predictive controller's path level
depends on the commands up to its instant only), each Householder vector is as short as
the rows reached so far: a compiled QR that follows that profile
(:mod:`~dqcontrol.controllers.linalg.householder`) does a fraction of the work of a dense one;
otherwise LAPACK's (``dgeqrf``, ``dormqr``).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from dqcontrol._compiled import compiled
from dqcontrol.controllers.linalg.householder import applied_q, pivoted_qr, profile_qr

__all__ = ["RANK_TOLERANCE", "compiled_null_space", "null_space"]

#: A pivot of the QR below this share of the largest one counts as zero.
RANK_TOLERANCE = 1e-10
#: Without pivoting, the smallest pivot must be at least this share of the largest.
_FULL_RANK_SHARE = 1e-8
#: The profile QR is used where its work is at most this share of a dense QR's.
_PROFILE_SHARE = 0.5
#: The pivoted QR is compiled for rows ``(r, n)`` with ``n r min(n, r)`` up to this.
_SMALL_WORK = 1 << 18


def null_space(rows: np.ndarray) -> np.ndarray:
    """An orthonormal basis ``(n, n - rank)`` of the null space of ``rows`` ``(r, n)``."""
    outcome, basis = compiled_null_space(np.ascontiguousarray(rows))
    if outcome == _DONE:
        return basis
    if outcome == _DENSE:
        complement = _lapack_complement(rows)
        if complement is not None:
            return complement
    return _pivoted(rows)


#: Outcomes of :func:`_profile_complement` and :func:`compiled_null_space`.
_DONE, _DEPENDENT, _DENSE = 0, 1, 2


@compiled
def _clearly_independent(pivots: np.ndarray) -> bool:
    """Every pivot of the QR at least :data:`_FULL_RANK_SHARE` of the largest (not NaN)."""
    smallest = np.inf
    largest = 0.0
    for p in pivots:
        smallest = min(smallest, abs(p))
        largest = max(largest, abs(p))
        if p != p:
            return False
    return smallest >= _FULL_RANK_SHARE * largest and largest > 0.0


@compiled
def _profile(columns: np.ndarray) -> np.ndarray:
    """Per column ``j`` of ``columns`` ``(n, r)`` the last row its Householder vector
    reaches: the last non-zero row of columns ``0 … j``, and at least ``j``."""
    n, r = columns.shape
    reach = np.empty(r, dtype=np.int64)
    last = -1
    for j in range(r):
        for i in range(n - 1, last, -1):
            if columns[i, j] != 0.0:
                last = i
                break
        reach[j] = max(last, j)
    return reach


@compiled
def _profile_work(reach: np.ndarray, n: int) -> int:
    """The multiply-adds of the profile QR and of forming the basis from it (``n``
    variables)."""
    r = reach.size
    work = 0
    for j in range(r):
        work += (reach[j] - j + 1) * (r - 1 - j + n - r)
    return work


@compiled
def _profile_complement(columns: np.ndarray) -> tuple[int, np.ndarray]:
    """``(outcome, basis)`` of the rows ``columns`` ``(n, r)`` (``Rᵀ``, overwritten):
    :data:`_DENSE` where the profile saves too little (the basis is then empty),
    :data:`_DEPENDENT` where a pivot is not clearly non-zero, :data:`_DONE` with the basis."""
    n, r = columns.shape
    reach = _profile(columns)
    dense = _profile_work(np.full(r, n - 1), n)
    if _profile_work(reach, n) > _PROFILE_SHARE * dense:
        return _DENSE, np.zeros((n, 0))
    tau, pivots = profile_qr(columns, reach)
    if not _clearly_independent(pivots):
        return _DEPENDENT, np.zeros((n, 0))
    return _DONE, applied_q(columns, reach, tau, r)


def _lapack_complement(rows: np.ndarray) -> np.ndarray | None:
    """The basis of clearly independent rows from LAPACK's QR (``dgeqrf``, ``dormqr``)."""
    r, n = rows.shape
    qr, tau, _work, info = lapack.dgeqrf(np.array(rows.T, order="F"))
    if info != 0:
        return None
    if not _clearly_independent(np.diagonal(qr).copy()):
        return None
    tail = np.zeros((n, n - r), order="F")
    tail[r:] = np.eye(n - r)
    basis, _work, info = lapack.dormqr("L", "N", qr, tau, tail, max(1, 64 * (n - r)))
    return None if info != 0 else np.ascontiguousarray(basis)


def _pivoted(rows: np.ndarray) -> np.ndarray:
    """The basis from a QR with column pivoting (rank-revealing): compiled for small
    ``rows``, LAPACK's otherwise. The basis is ``Q`` of the first ``rank`` reflectors only:
    the later ones factor rounding errors, and would only turn the basis within the null
    space."""
    r, n = rows.shape
    if n * r * min(n, r) > _SMALL_WORK:
        return _lapack_pivoted(rows)
    return _pivoted_complement(np.ascontiguousarray(rows.T))


@compiled
def _rank(pivots: np.ndarray) -> int:
    """The pivots above :data:`RANK_TOLERANCE` of the first (the largest)."""
    largest = abs(pivots[0]) if pivots.size else 0.0
    if not largest > 0.0:
        return 0
    return int(np.sum(np.abs(pivots) > RANK_TOLERANCE * largest))


@compiled
def _pivoted_complement(columns: np.ndarray) -> np.ndarray:
    """:func:`_pivoted` of the rows ``columns`` ``(n, r)`` (``Rᵀ``, overwritten)."""
    n = columns.shape[0]
    tau, pivots = pivoted_qr(columns)
    rank = _rank(pivots)
    if rank == n:
        return np.zeros((n, 0))
    return applied_q(columns, np.full(rank, n - 1), tau[:rank], rank)


@compiled
def compiled_null_space(rows: np.ndarray) -> tuple[int, np.ndarray]:
    """``(outcome, basis)``: :data:`_DONE` with the basis of :func:`null_space` where its
    compiled factorisations give it; otherwise the basis is empty and the outcome names
    the LAPACK factorisation :func:`null_space` takes instead: :data:`_DENSE` (rows
    without a profile to follow: ``dgeqrf``, then the pivoted QR should they not be
    clearly independent) or :data:`_DEPENDENT` (rows too many for the compiled pivoted QR:
    ``dgeqp3``)."""
    r, n = rows.shape
    if r == 0:
        return _DONE, np.eye(n)
    if r < n:
        outcome, basis = _profile_complement(np.ascontiguousarray(rows.T))
        if outcome != _DEPENDENT:
            return outcome, basis
    if n * r * min(n, r) > _SMALL_WORK:
        return _DEPENDENT, np.zeros((n, 0))
    return _DONE, _pivoted_complement(np.ascontiguousarray(rows.T))


def _lapack_pivoted(rows: np.ndarray) -> np.ndarray:
    """:func:`_pivoted` from LAPACK (``dgeqp3``, ``dorgqr``)."""
    r, n = rows.shape
    qr, _pivots, tau, _work, info = lapack.dgeqp3(np.array(rows.T, order="F"))
    if info != 0:
        raise np.linalg.LinAlgError(f"dgeqp3 failed (info {info})")
    k = min(n, r)
    rank = _rank(np.diagonal(qr)[:k].copy())
    if rank == n:
        return np.zeros((n, 0))
    reflectors = np.zeros((n, n), order="F")
    reflectors[:, :rank] = qr[:, :rank]
    q, _work, info = lapack.dorgqr(reflectors, tau[:rank])
    if info != 0:
        raise np.linalg.LinAlgError(f"dorgqr failed (info {info})")
    return np.ascontiguousarray(q[:, rank:])
