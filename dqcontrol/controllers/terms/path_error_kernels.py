"""The compiled loops of the path error's rows (:mod:`.path_error`).

Each sum runs over its index in increasing order from ``0.0``, the order of numpy's
``einsum`` for these contractions (the results are the same, bit for bit); the products
that fill the rows are single multiplications.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["fill_path_rows", "projectors_into"]


@compiled
def projectors_into(poses: np.ndarray, basis: np.ndarray, out: np.ndarray) -> None:
    """``out[i] = Σ_k poses[i, k] basis[k]`` for poses ``(p, 8)`` and ``basis``
    ``(8, 6, 8)`` (``out`` ``(p, 6, 8)``)."""
    for i in range(poses.shape[0]):
        for a in range(basis.shape[1]):
            for b in range(basis.shape[2]):
                s = 0.0
                for k in range(basis.shape[0]):
                    s += poses[i, k] * basis[k, a, b]
                out[i, a, b] = s


@compiled
def fill_path_rows(
    proj: np.ndarray,
    jacobians: np.ndarray,
    weights: np.ndarray,
    phase_weights: np.ndarray,
    pd: np.ndarray,
    pj: np.ndarray,
    rows: np.ndarray,
) -> None:
    """``pj[i] = E_i J_i`` ``(p, 6, n)`` and the rows ``(p, 6, p, n + 1)``: block ``(i, j)``
    holds ``weights[i, j] E_i J_i`` on ``qd_j`` and ``-phase_weights[i, j] E_i x_d'`` on
    ``s_j`` (``pd[i] = E_i x_d'``)."""
    p, r, k = proj.shape
    n = jacobians.shape[2]
    for i in range(p):
        for a in range(r):
            for c in range(n):
                s = 0.0
                for b in range(k):
                    s += proj[i, a, b] * jacobians[i, b, c]
                pj[i, a, c] = s
        for a in range(r):
            for j in range(p):
                w = weights[i, j]
                for c in range(n):
                    rows[i, a, j, c] = w * pj[i, a, c]
                rows[i, a, j, n] = -phase_weights[i, j] * pd[i, a]
