"""A reduced level solved on its last active set in one compiled call (docs/theory.md §7.5).

A level reduced to the null space of the levels above is formed in four compiled steps:
its residual rows in the basis and their Gram matrix
(:func:`~dqcontrol.controllers.core.reduced.objective_in_basis`), every limit's rows in the basis
(:func:`~dqcontrol.controllers.core.reduced.rows_in_basis`), the Cholesky factor of its Hessian,
and the solve on the guessed active set with its check
(:func:`~dqcontrol.controllers.backends.daqp.active_set.solve_on_active_set`). Here one call
runs the four in that order with the same kernels, so its answer is theirs bit for bit,
without the Python between them. The caller falls back to the dense QP (and DAQP) where
the call does not end with a checked optimum.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.backends.daqp.active_set import dense_factor, solve_on_active_set
from dqcontrol.controllers.core.reduced import _entry_rows, _rows_in_basis, _weighted_gram
from dqcontrol.controllers.linalg.cholesky import cholesky_into

__all__ = ["INVALID_BOUNDS", "NOT_DEFINITE", "reduced_on_active_set"]

#: Returned by :func:`reduced_on_active_set` beyond the statuses of ``solve_on_active_set``.
INVALID_BOUNDS, NOT_DEFINITE = 4, 5
#: No entries: the rows in the basis are given dense (``sparse`` False).
_DENSE_CHECK = np.zeros((0, 3))


@compiled
def reduced_on_active_set(
    entries: np.ndarray,
    b: np.ndarray,
    scale: np.ndarray,
    basis: np.ndarray,
    point: np.ndarray,
    general: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    active: np.ndarray,
    at_upper: np.ndarray,
    settings: np.ndarray,
    rows: np.ndarray,
    qp_rows: np.ndarray,
    qp_lower: np.ndarray,
    qp_upper: np.ndarray,
    y: np.ndarray,
    duals: np.ndarray,
) -> tuple[int, np.ndarray, np.ndarray, int, np.ndarray, np.ndarray]:
    """The level of the stacked residual rows (``entries``, ``b``, ``scale``:
    :class:`~dqcontrol.controllers.core.reduced.LevelRows`) in ``z = point + basis y``, under
    the rows ``[I; C]`` (``general``: the non-zero entries of ``C``; ``lower``/``upper``
    theirs), solved from the guess ``active``/``at_upper``.

    ``settings`` is ``(primal_tol, dual_tol, max_changes, pivot_share)``. Writes the level's
    rows ``[A basis | A point - b]`` into ``rows``, the QP's rows and bounds in ``y`` into
    ``qp_rows``, ``qp_lower``, ``qp_upper``, and ``y`` and ``duals`` where solved. Returns
    ``(status, active, at_upper, changes, hessian, gradient)``: the status of
    ``solve_on_active_set``, or :data:`INVALID_BOUNDS` (a lower bound above its upper one
    or NaN), or :data:`NOT_DEFINITE` (the Hessian is not safely positive definite).
    """
    row_scale = np.empty(rows.shape[0])
    _entry_rows(entries, basis, point, b, 1.0, scale, rows, row_scale)
    hessian, gradient = _weighted_gram(rows, row_scale)
    _rows_in_basis(general, basis, point, lower, upper, qp_rows, qp_lower, qp_upper)
    for i in range(qp_lower.shape[0]):
        if not qp_lower[i] <= qp_upper[i]:
            return INVALID_BOUNDS, active, at_upper, 0, hessian, gradient
    factor = np.zeros(hessian.shape)
    if not cholesky_into(hessian, factor, settings[3], 0.0):
        return NOT_DEFINITE, active, at_upper, 0, hessian, gradient
    status, active, at_upper, changes = solve_on_active_set(
        dense_factor(factor), gradient, qp_rows[hessian.shape[0] :], _DENSE_CHECK, False,
        qp_lower, qp_upper, active, at_upper,
        settings[0], settings[1], int(settings[2]), y, duals,
    )  # fmt: skip
    return status, active, at_upper, changes, hessian, gradient
