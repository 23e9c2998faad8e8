"""The compiled loops of the path error's rows (:mod:`.path_error`).

The sums over the projector basis run in increasing order from ``0.0``. The contractions
of the residual's ``b`` over a contiguous axis (``E_i x_d'``, ``E_i (x̄_i - x_d)``,
``E_i J_i (q_base - q̄)``) are summed as numpy's ``einsum`` sums them (:func:`lane_dot`),
so the rows are those of the numpy formation, bit for bit; the products that fill the
rows are single multiplications.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.linalg.lanes import lane_dot

__all__ = [
    "path_states_into",
    "projectors_into",
]


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
def path_states_into(
    poses: np.ndarray,
    targets: np.ndarray,
    target_derivatives: np.ndarray,
    jacobians: np.ndarray,
    q_base: np.ndarray,
    q_lin: np.ndarray,
    sigma_base: np.ndarray,
    sigma_lin: np.ndarray,
    basis: np.ndarray,
    b: np.ndarray,
    states: np.ndarray,
) -> None:
    """The rows of each state ``states`` ``(p, 6, n + 1)``, ``[E_i J_i | -E_i x_d'_i]``, and
    ``b`` ``(6 p,)`` of the linearised path error.

    With ``E_i = Σ_k poses[i, k] basis[k]`` ``(6, 8)``,
    ``b_i = -(E_i (x̄_i - x_d,i) + E_i J_i (q_base_i - q̄_i) - E_i x_d'_i (σ_base,i - σ̄_i))``
    (``q_base``, ``σ_base``: the states of the zero decision; ``q̄``, ``σ̄``: the
    linearisation point ``q_lin``, ``sigma_lin``)."""
    p, n = jacobians.shape[0], jacobians.shape[2]
    r, k = basis.shape[1], basis.shape[2]
    proj = np.empty((r, k))
    gap = np.empty(k)
    dq = np.empty(n)
    for i in range(p):
        for a in range(r):
            for c in range(k):
                s = 0.0
                for e in range(basis.shape[0]):
                    s += poses[i, e] * basis[e, a, c]
                proj[a, c] = s
        for c in range(k):
            gap[c] = poses[i, c] - targets[i, c]
        for c in range(n):
            dq[c] = q_base[i, c] - q_lin[i, c]
        ds = sigma_base[i] - sigma_lin[i]
        for a in range(r):
            pj = states[i, a]
            for c in range(n):
                s = 0.0
                for e in range(k):
                    s += proj[a, e] * jacobians[i, e, c]
                pj[c] = s
            pd = lane_dot(proj[a], target_derivatives[i])
            value = lane_dot(proj[a], gap) + lane_dot(pj[:n], dq)
            b[i * r + a] = -(value - pd * ds)
            pj[n] = -pd
