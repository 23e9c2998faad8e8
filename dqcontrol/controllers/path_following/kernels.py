"""The compiled linearisation check of the path-following step
(:mod:`~dqcontrol.controllers.path_following.controller`): how far the first state's
linearised path error is from the true one. :func:`tangent_mismatch` sums its products in
increasing order (a threshold's input, not a row of the problem).
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["tangent_mismatch"]


@compiled
def tangent_mismatch(
    pose: np.ndarray,
    target: np.ndarray,
    basis: np.ndarray,
    rows: np.ndarray,
    b: np.ndarray,
    z: np.ndarray,
) -> float:
    """``max_a |e_a - (rows z - b)_a|`` over the ``r`` rows of ``basis`` ``(8, r, 8)``:
    ``e = E(x) (x - x_d)`` the tangent error of ``pose`` (negated where ``x · x_d < 0``)
    against ``target``, ``E(x) = Σ_k x_k basis[k]``; NaN if a difference is NaN."""
    k = pose.shape[0]
    dot = 0.0
    for c in range(k):
        dot += pose[c] * target[c]
    sign = -1.0 if dot < 0.0 else 1.0
    out = -np.inf
    for a in range(basis.shape[1]):
        err = 0.0
        for c in range(k):
            e = 0.0
            for j in range(basis.shape[0]):
                e += (sign * pose[j]) * basis[j, a, c]
            err += e * (sign * pose[c] - target[c])
        lin = 0.0
        for j in range(z.shape[0]):
            lin += rows[a, j] * z[j]
        d = abs(err - (lin - b[a]))
        if d != d:
            return d
        if d > out:
            out = d
    return out
