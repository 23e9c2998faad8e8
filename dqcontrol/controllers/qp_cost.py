"""The QP Hessian of the tracking controllers in compiled calls (the 1 kHz step).

For one instant the cost of FORMULATION §5 is ``λ1 ‖J qd - w s‖² + qdᵀ D qd (+ stall)``
in ``z = [qd, s]``, i.e. ``½ zᵀ H z`` with ``H = 2 (λ1 Gᵀ G + D)``, ``G = [J, -w]`` and
``-w = K (x - x_d) - dx_d/dσ``. :func:`local_hessian` builds ``H`` from the pose, its
Jacobian and the target pair on floats, compiled with Numba: the same arithmetic as the
general step's ``P`` (``TrackingController._step_general``), in one call instead of a
dozen numpy calls on 8×8 arrays. ``tests/test_local_fast.py`` checks the two steps agree.
:func:`instant_p_values` does the same for the p instants of the predictive controller,
straight to the values of ``P``'s stored upper triangles, and :func:`scatter_symmetric`
writes such values into DAQP's dense ``H``.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["gram", "instant_p_values", "local_hessian", "scatter_symmetric"]


@compiled
def gram(g: np.ndarray) -> np.ndarray:
    """``Gᵀ G`` (m, m) of ``G`` (8, m), new, symmetric: each entry the plain sum over the
    8 rows in order. The general step's single instant uses it too, so that its ``P`` and
    :func:`local_hessian`'s are the same numbers bit for bit (a BLAS product sums in its
    own order)."""
    m = g.shape[1]
    h = np.empty((m, m))
    for i in range(m):
        for j in range(i, m):
            acc = 0.0
            for k in range(g.shape[0]):
                acc += g[k, i] * g[k, j]
            h[i, j] = acc
            h[j, i] = acc
    return h


@compiled
def _task_matrix(
    x: np.ndarray, jac: np.ndarray, xd: np.ndarray, dxd: np.ndarray, gain: float, g: np.ndarray
) -> None:
    """``g = G = [J, K (x - x_d) - dx_d/dσ]`` (8, n+1) of one instant, after negating ``x``
    and ``jac`` in place when ``x · x_d < 0`` (the error between the nearer of ``±x`` and
    ``x_d``)."""
    n = jac.shape[1]
    align = 0.0
    for k in range(8):
        align += x[k] * xd[k]
    if align < 0.0:
        for k in range(8):
            x[k] = -x[k]
            for j in range(n):
                jac[k, j] = -jac[k, j]
    for k in range(8):
        for j in range(n):
            g[k, j] = jac[k, j]
        g[k, n] = gain * (x[k] - xd[k]) - dxd[k]


@compiled
def local_hessian(
    x: np.ndarray,
    jac: np.ndarray,
    pair: np.ndarray,
    gain_per_s: float,
    two_task_weight: float,
    diag2: np.ndarray,
    two_stall: float,
) -> np.ndarray:
    """``H = 2 λ1 Gᵀ G + 2 D (+ 2 μ_stall on the qd diagonal)``, ``(n+1, n+1)``, new.

    ``x`` (8,) and ``jac`` (8, n) are the pose and its Jacobian (fresh arrays: they are
    negated in place when ``x · x_d < 0``, so that the error is formed between the
    nearer of ``±x`` and ``x_d``); ``pair`` is ``[x_d; dx_d/dσ]`` (2, 8); ``diag2`` is
    ``2 D`` (n+1, n+1); ``two_task_weight`` is ``2 λ1`` and ``two_stall`` ``2 μ_stall``
    times the stall factor (0 unless stalled).
    """
    n = jac.shape[1]
    m = n + 1
    g = np.empty((8, m))
    _task_matrix(x, jac, pair[0], pair[1], gain_per_s, g)
    h = gram(g)
    for i in range(m):
        for j in range(m):
            h[i, j] = h[i, j] * two_task_weight + diag2[i, j]
        if i < n:
            h[i, i] += two_stall
    return h


@compiled
def instant_p_values(
    xs: np.ndarray,
    jacs: np.ndarray,
    xd: np.ndarray,
    dxd: np.ndarray,
    gain_per_s: float,
    task_weight: float,
    gather: np.ndarray,
    diag_values: np.ndarray,
    stall: float,
    qd_diag_pos: np.ndarray,
) -> np.ndarray:
    """The stored values of ``P = 2 (λ1 blkdiag(G_iᵀ G_i) + D (+ stall))`` for p instants.

    ``xs`` (p, 8), ``jacs`` (p, 8, n): predicted poses and Jacobians (fresh: negated in
    place where ``x_i · x_d,i < 0``); ``xd``, ``dxd`` (p, 8): targets and their
    σ-derivatives; ``G_i = [J_i, K (x_i - x_d,i) - dx_d,i]``. ``gather`` indexes the
    stored entries in the flattened ``(p, m, m)`` blocks, ``diag_values`` is ``D`` at
    those entries, ``qd_diag_pos`` the positions of the ``qd`` diagonal among them.
    """
    p, n = jacs.shape[0], jacs.shape[2]
    m = n + 1
    blocks = np.empty((p, m, m))
    g = np.empty((8, m))
    for i in range(p):
        _task_matrix(xs[i], jacs[i], xd[i], dxd[i], gain_per_s, g)
        blocks[i] = gram(g)
    flat = blocks.ravel()
    values = np.empty(gather.shape[0])
    for e in range(gather.shape[0]):
        values[e] = flat[gather[e]] * task_weight + diag_values[e]
    for e in qd_diag_pos:
        values[e] += stall
    for e in range(values.shape[0]):
        values[e] *= 2.0
    return values


@compiled
def scatter_symmetric(
    h: np.ndarray, rows: np.ndarray, cols: np.ndarray, values: np.ndarray
) -> None:
    """``h[rows, cols] = h[cols, rows] = values`` (the upper triangle's entries, mirrored)."""
    for e in range(values.shape[0]):
        h[rows[e], cols[e]] = values[e]
        h[cols[e], rows[e]] = values[e]
