"""A dense QP solved on a guessed active set, and the check that the guess was right
(docs/theory.md §7.5).

For ``min ½ zᵀ P z + cᵀ z  s.t.  lower ≤ A z ≤ upper`` with ``P`` positive definite, a set
``W`` of rows held at one of their bounds (``b_W``) gives the equality-constrained optimum

    z = -P⁻¹ (c + A_Wᵀ λ),   (A_W P⁻¹ A_Wᵀ) λ = -(b_W + A_W P⁻¹ c),

computed with a factor ``P = F Fᵀ`` (``Y = F⁻¹ A_Wᵀ``, ``g = F⁻¹ c``: the system is
``YᵀY λ = -(b_W + Yᵀ g)`` and ``z = -F⁻ᵀ (g + Y λ)``): the dense Cholesky factor ``L``, or
the first level's factor in the predicted states
(:mod:`~dqcontrol.controllers.backends.daqp.state_factor`). A factor is the tuple ``(L,
diagonal, below, inverse_scales)``, the last three empty for a dense one
(:func:`dense_factor`). The point is *the* optimum of the QP exactly when the KKT
conditions hold: every row within its bounds and every multiplier of the right sign (``λ ≥
0`` at an upper bound, ``≤ 0`` at a lower one, free where both bounds are equal). From one
control step to the next the active set rarely changes, so the last step's set is a good
guess, and checking it costs a factorisation and one pass over the rows, where an
active-set solver given new data would start by transforming every row.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.backends.daqp.state_factor import (
    state_backward,
    state_forward,
    state_forward_rows,
)
from dqcontrol.controllers.linalg.cholesky import cholesky_into

__all__ = ["dense_factor", "solve_on_active_set"]

#: Returned by :func:`solve_on_active_set`.
SOLVED, DEPENDENT_ROWS, INFEASIBLE, WRONG_SIGN = 0, 1, 2, 3


@compiled
def _forward(factor: np.ndarray, b: np.ndarray, out: np.ndarray, first: int = 0) -> None:
    """``out = L⁻¹ b`` for the lower triangular ``factor``, where ``b`` is zero before the
    index ``first``."""
    out[:first] = 0.0
    for i in range(first, b.shape[0]):
        s = b[i]
        for k in range(first, i):
            s -= factor[i, k] * out[k]
        out[i] = s / factor[i, i]


@compiled
def _backward(factor: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """``out = L⁻ᵀ b`` for the lower triangular ``factor``."""
    n = b.shape[0]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for k in range(i + 1, n):
            s -= factor[k, i] * out[k]
        out[i] = s / factor[i, i]


@compiled
def dense_factor(lower: np.ndarray) -> tuple:
    """The factor tuple of the dense lower Cholesky factor ``lower``."""
    return lower, np.zeros((0, 0, 0)), np.zeros((0, 0, 0)), np.zeros((0, 0))


@compiled
def _factor_forward(factor: tuple, b: np.ndarray, out: np.ndarray) -> None:
    """``out = F⁻¹ b``."""
    if factor[1].shape[0]:
        state_forward((factor[1], factor[2], factor[3]), b, out)
    else:
        _forward(factor[0], b, out)


@compiled
def _factor_backward(factor: tuple, b: np.ndarray, out: np.ndarray) -> None:
    """``out = F⁻ᵀ b``."""
    if factor[1].shape[0]:
        state_backward((factor[1], factor[2], factor[3]), b, out)
    else:
        _backward(factor[0], b, out)


@compiled
def _factor_forward_rows(factor: tuple, held: np.ndarray, yt: np.ndarray) -> None:
    """``yt[:, j] = F⁻¹ held[j]`` for every row of ``held``."""
    if factor[1].shape[0]:
        state_forward_rows((factor[1], factor[2], factor[3]), held, yt)
    else:
        _forward_rows(factor[0], held, yt)


@compiled
def solve_on_active_set(
    factor: tuple,
    c: np.ndarray,
    general: np.ndarray,
    entries: np.ndarray,
    sparse: bool,
    lower: np.ndarray,
    upper: np.ndarray,
    active: np.ndarray,
    at_upper: np.ndarray,
    primal_tol: float,
    dual_tol: float,
    max_changes: int,
    z: np.ndarray,
    duals: np.ndarray,
) -> tuple[int, np.ndarray, np.ndarray, int]:
    """The optimum from the guessed active set ``active`` (row indices of ``A = [I; C]``,
    a backend's rows; ``at_upper[j]``: the row ``active[j]`` is held at its upper bound,
    else its lower one), checked, and mended up to ``max_changes`` times.

    ``factor`` is a factor of ``P`` (the module docstring). ``C`` (row ``n + i`` of ``A``
    is its row ``i``) is ``general``, dense, or where ``sparse`` its non-zero ``entries``
    (:func:`~dqcontrol.controllers.linalg.entries.nonzero_entries`; ``general`` is then not
    read): the same sums without their zero terms. The point is the optimum when the KKT
    conditions hold: every row within ``primal_tol`` times its norm (at least 1) of its
    bounds, every multiplier of the right sign to ``dual_tol`` times the largest. Where
    they fail, the most broken row joins the set at the bound it breaks or, with every row
    met, the multiplier of the most wrong sign leaves it, and the check runs again.

    Writes ``z`` and ``duals`` (one per row of ``A``, zero off the set; positive at an
    upper bound) and returns ``(status, active, at_upper, changes)``: ``SOLVED`` (0) with
    the set of the optimum and how many rows joined or left it, or why the last set
    failed: ``DEPENDENT_ROWS`` (its rows are not independent enough to give unique
    multipliers), ``INFEASIBLE`` (a row out of its bounds) or ``WRONG_SIGN``.
    """
    status = SOLVED
    for changes in range(max_changes + 1):
        lam = np.zeros(active.shape[0])
        held = _active_rows(general, entries, sparse, active, c.shape[0])
        if not _equality_optimum(factor, c, held, lower, upper, active, at_upper, z, lam):
            return DEPENDENT_ROWS, active, at_upper, changes
        if sparse:
            row, above = _worst_sparse_row(entries, lower, upper, z, primal_tol)
        else:
            row, above = _worst_row(general, lower, upper, z, primal_tol)
        if row >= 0:
            status = INFEASIBLE
            active, at_upper = _joined(active, at_upper, row, above)
            continue
        j = _worst_multiplier(lower, upper, active, at_upper, lam, dual_tol)
        if j >= 0:
            status = WRONG_SIGN
            active, at_upper = _left(active, at_upper, j)
            continue
        duals[:] = 0.0
        for i in range(active.shape[0]):
            duals[active[i]] = lam[i]
        return SOLVED, active, at_upper, changes
    return status, active, at_upper, max_changes + 1


@compiled
def _joined(
    active: np.ndarray, at_upper: np.ndarray, row: int, above: bool
) -> tuple[np.ndarray, np.ndarray]:
    """The set with ``row`` joined at its upper (``above``) or lower bound (new arrays,
    filled entry by entry: ``np.append`` would compile NumPy's shape checks and their
    messages into every kernel that calls it)."""
    k = active.shape[0]
    rows = np.empty(k + 1, dtype=active.dtype)
    upper = np.empty(k + 1, dtype=np.bool_)
    for i in range(k):
        rows[i] = active[i]
        upper[i] = at_upper[i]
    rows[k] = row
    upper[k] = above
    return rows, upper


@compiled
def _left(active: np.ndarray, at_upper: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray]:
    """The set without its entry ``j`` (new arrays)."""
    k = active.shape[0]
    rows = np.empty(k - 1, dtype=active.dtype)
    upper = np.empty(k - 1, dtype=np.bool_)
    for i in range(k - 1):
        source = i if i < j else i + 1
        rows[i] = active[source]
        upper[i] = at_upper[source]
    return rows, upper


@compiled
def _entries_start(entries: np.ndarray, row: int) -> int:
    """The first entry of ``row`` or of a later row (``entries`` row by row)."""
    low, high = 0, entries.shape[0]
    while low < high:
        mid = (low + high) // 2
        if entries[mid, 0] < row:
            low = mid + 1
        else:
            high = mid
    return low


@compiled
def _active_rows(
    general: np.ndarray, entries: np.ndarray, sparse: bool, active: np.ndarray, n: int
) -> np.ndarray:
    """The rows ``active`` of ``[I; C]`` dense, ``(k, n)`` (``C`` as in
    :func:`solve_on_active_set`)."""
    rows = np.zeros((active.shape[0], n))
    for j in range(active.shape[0]):
        row = active[j]
        if row < n:
            rows[j, row] = 1.0
        elif sparse:
            e = _entries_start(entries, row - n)
            while e < entries.shape[0] and int(entries[e, 0]) == row - n:
                rows[j, int(entries[e, 1])] = entries[e, 2]
                e += 1
        else:
            rows[j] = general[row - n]
    return rows


@compiled
def _forward_rows(factor: np.ndarray, held: np.ndarray, yt: np.ndarray) -> None:
    """``yt[:, j] = L⁻¹ a_j`` for the rows ``a_j = held[j]``, together: each entry is the
    sum :func:`_forward` forms, in its order, and the sums of the rows run side by side
    (the inner loop along a row of ``yt``, which the compiler vectorises). Below a row's
    first non-zero entry its column is zero, as there."""
    k, n = held.shape
    start = n
    for j in range(k):
        start = min(start, _first_nonzero(held[j]))
    yt[:start] = 0.0
    s = np.empty(k)
    for i in range(start, n):
        for j in range(k):
            s[j] = held[j, i]
        for m in range(start, i):
            lim = factor[i, m]
            line = yt[m]
            for j in range(k):
                s[j] -= lim * line[j]
        pivot = factor[i, i]
        out = yt[i]
        for j in range(k):
            out[j] = s[j] / pivot


@compiled
def _equality_optimum(
    factor: tuple,
    c: np.ndarray,
    held: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    active: np.ndarray,
    at_upper: np.ndarray,
    z: np.ndarray,
    lam: np.ndarray,
) -> bool:
    """``z`` and the multipliers ``lam`` of the optimum with the rows ``active`` (``held``:
    them, dense) held at their bounds; False when those rows are not independent enough."""
    n, k = c.shape[0], active.shape[0]
    g = np.empty(n)
    _factor_forward(factor, c, g)
    yt = np.empty((n, k))  # columns: F⁻¹ a_j
    _factor_forward_rows(factor, held, yt)
    schur = np.zeros((k, k))
    dots = np.zeros(k)
    for m in range(n):
        line = yt[m]
        gm = g[m]
        for i in range(k):
            dots[i] += line[i] * gm
            for j in range(i + 1):
                schur[i, j] += line[i] * line[j]
    rhs = np.empty(k)
    for i in range(k):
        row = active[i]
        bound = upper[row] if at_upper[i] else lower[row]
        rhs[i] = -(bound + dots[i])
        for j in range(i):
            schur[j, i] = schur[i, j]
    if k:
        schur_factor = np.zeros((k, k))
        if not cholesky_into(schur, schur_factor, 1e-12, 0.0):
            return False
        half = np.empty(k)
        _forward(schur_factor, rhs, half)
        _backward(schur_factor, half, lam)
    v = g.copy()
    for m in range(n):
        line = yt[m]
        for j in range(k):
            v[m] += line[j] * lam[j]
    _factor_backward(factor, v, z)
    for m in range(n):
        z[m] = -z[m]
    return True


@compiled
def _worst_box_row(
    lower: np.ndarray, upper: np.ndarray, z: np.ndarray, primal_tol: float
) -> tuple[float, int, bool]:
    """Over the rows of ``I``: how far the worst one is out of its bounds beyond
    ``primal_tol`` (else ``primal_tol``), which (-1: none) and whether above; a NaN in
    ``z`` is its row, with the distance ``-1``."""
    worst, row, above = primal_tol, -1, False
    for r in range(z.shape[0]):
        if z[r] - upper[r] > worst:
            worst, row, above = z[r] - upper[r], r, True
        elif lower[r] - z[r] > worst:
            worst, row, above = lower[r] - z[r], r, False
        elif not (z[r] == z[r]):
            return -1.0, r, False
    return worst, row, above


@compiled
def _breach(value: float, norm2: float, low: float, up: float, worst: float) -> tuple:
    """``(distance, above)`` of a row of value ``value`` and squared norm ``norm2`` out of
    ``[low, up]`` by more than ``worst`` times its norm (at least 1), the distance over
    that norm; ``(0, False)`` where it is not."""
    norm = max(math.sqrt(norm2), 1.0)
    if value - up > worst * norm:
        return (value - up) / norm, True
    if low - value > worst * norm:
        return (low - value) / norm, False
    return 0.0, False


@compiled
def _worst_row(
    general: np.ndarray, lower: np.ndarray, upper: np.ndarray, z: np.ndarray, primal_tol: float
) -> tuple[int, bool]:
    """The row of ``[I; C]`` (``general``: ``C``) furthest out of its bounds beyond
    ``primal_tol`` (distances over the row's norm, or over 1 for a row shorter than that:
    a row that vanishes in a reduced level keeps an absolute tolerance) and whether it is
    above its upper bound; ``(-1, False)`` when every row is within its bounds."""
    n = z.shape[0]
    worst, row, above = _worst_box_row(lower, upper, z, primal_tol)
    if worst < 0.0:
        return row, above
    for i in range(general.shape[0]):
        r, line = n + i, general[i]
        value = 0.0
        for m in range(n):
            value += line[m] * z[m]
        if lower[r] - worst <= value <= upper[r] + worst:
            continue  # within the bounds' tolerance for any norm of at least 1
        norm2 = 0.0
        for m in range(n):
            norm2 += line[m] * line[m]
        distance, high = _breach(value, norm2, lower[r], upper[r], worst)
        if distance > 0.0:
            worst, row, above = distance, r, high
    return row, above


@compiled
def _worst_sparse_row(
    entries: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    z: np.ndarray,
    primal_tol: float,
) -> tuple[int, bool]:
    """:func:`_worst_row` over the non-zero ``entries`` of ``C`` (row by row, columns in
    order): the same sums, without their zero terms."""
    n = z.shape[0]
    worst, row, above = _worst_box_row(lower, upper, z, primal_tol)
    if worst < 0.0:
        return row, above
    e, count = 0, entries.shape[0]
    for i in range(lower.shape[0] - n):
        r, first = n + i, e
        value = 0.0
        while e < count and int(entries[e, 0]) == i:
            value += entries[e, 2] * z[int(entries[e, 1])]
            e += 1
        if lower[r] - worst <= value <= upper[r] + worst:
            continue
        norm2 = 0.0
        for k in range(first, e):
            norm2 += entries[k, 2] * entries[k, 2]
        distance, high = _breach(value, norm2, lower[r], upper[r], worst)
        if distance > 0.0:
            worst, row, above = distance, r, high
    return row, above


@compiled
def _first_nonzero(values: np.ndarray) -> int:
    """The index of the first non-zero entry of ``values`` (its length if none)."""
    for i in range(values.shape[0]):
        if values[i] != 0.0:
            return i
    return values.shape[0]


@compiled
def _worst_multiplier(
    lower: np.ndarray,
    upper: np.ndarray,
    active: np.ndarray,
    at_upper: np.ndarray,
    lam: np.ndarray,
    dual_tol: float,
) -> int:
    """The position in ``active`` of the multiplier of the most wrong sign beyond
    ``dual_tol`` times the largest (free where a row's bounds are equal), or -1."""
    largest = 0.0
    for j in range(lam.shape[0]):
        largest = max(largest, abs(lam[j]))
    worst, position = dual_tol * largest, -1
    for j in range(lam.shape[0]):
        row = active[j]
        if lower[row] == upper[row]:
            continue
        wrong = -lam[j] if at_upper[j] else lam[j]
        if wrong > worst:
            worst, position = wrong, j
    return position
