"""The compiled bookkeeping of the path-following step (:mod:`.path_following`): the
applied plan from a solution, and the linearisation mismatch of the first state.

Each value of :func:`applied_plan` is numpy's, operation for operation (a clip is a
maximum then a minimum, both exact); :func:`tangent_mismatch` sums its products in
increasing order (a threshold's input, not a row of the problem).
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["applied_plan", "count_set", "tangent_mismatch"]


@compiled
def _clip(value: float, low: float, high: float) -> float:
    """``np.minimum(np.maximum(value, low), high)`` of one entry (NaN propagates)."""
    v = value if value >= low or value != value else low
    return v if v <= high or v != v else high


@compiled
def applied_plan(
    z: np.ndarray, lower: np.ndarray, upper: np.ndarray, s_max: float, num_blocks: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(qd (p, n), s (p,))`` of the decision ``z = [qd_0, s_0, qd_1, …]`` (fresh arrays):
    ``qd_0`` clipped to ``[lower, upper]`` ``(n,)``, every ``s_i`` to ``[0, s_max]``."""
    m = z.shape[0] // num_blocks
    n = m - 1
    qd = np.empty((num_blocks, n))
    s = np.empty(num_blocks)
    for i in range(num_blocks):
        for k in range(n):
            qd[i, k] = z[i * m + k]
        s[i] = _clip(z[i * m + n], 0.0, s_max)
    for k in range(n):
        qd[0, k] = _clip(qd[0, k], lower[k], upper[k])
    return qd, s


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


@compiled
def count_set(mask: np.ndarray) -> int:
    """How many entries of the boolean ``mask`` are set."""
    count = 0
    for k in range(mask.shape[0]):
        if mask[k]:
            count += 1
    return count
