"""The compiled check of the singularity damping (:mod:`.singularity_damping`): whether the
tangent Jacobian's smallest singular value is clearly above the threshold, without an SVD.

``σ_min(T) > ρ`` exactly when ``G - ρ² I`` is positive definite, ``G`` the smaller of the
Gram matrices ``T Tᵀ`` and ``Tᵀ T``; a Cholesky factorisation of it succeeds then. The
check is given a threshold a little above ``ε`` (see the term), so that rounding in ``T``,
``G`` and the factorisation cannot call a value at or below ``ε`` clear.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.linalg.cholesky import cholesky_into

__all__ = ["clearly_regular"]


@compiled
def clearly_regular(
    pose: np.ndarray, jacobian: np.ndarray, basis: np.ndarray, threshold_sq: float
) -> bool:
    """Whether ``G - threshold_sq I`` is positive definite (Cholesky), for ``T = E J``,
    ``E = Σ_k pose[k] basis[k]`` ``(r, 8)``, ``J`` = ``jacobian`` ``(8, n)``; False for NaN."""
    r, k = basis.shape[1], basis.shape[2]
    n = jacobian.shape[1]
    proj = np.zeros((r, k))
    for a in range(r):
        for c in range(k):
            s = 0.0
            for e in range(basis.shape[0]):
                s += pose[e] * basis[e, a, c]
            proj[a, c] = s
    tangent = np.zeros((r, n))
    for a in range(r):
        for c in range(n):
            s = 0.0
            for e in range(k):
                s += proj[a, e] * jacobian[e, c]
            tangent[a, c] = s
    rows = r <= n  # the Gram matrix of the rows (T Tᵀ) or of the columns (Tᵀ T)
    size = r if rows else n
    gram = np.zeros((size, size))
    for i in range(size):
        for j in range(i + 1):
            s = 0.0
            for e in range(n if rows else r):
                s += tangent[i, e] * tangent[j, e] if rows else tangent[e, i] * tangent[e, j]
            gram[i, j] = s
    return cholesky_into(gram, gram, 0.0, threshold_sq)
