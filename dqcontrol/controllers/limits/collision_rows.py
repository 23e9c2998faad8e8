"""The collision limit's rows from the pairs found close, compiled (docs/theory.md §10.2,
§10.3).

Both forms take the pairs of one batched query (configuration, pair, distance, gradient)
and write the rows in one pass, where numpy would need a few dozen small calls; a pair whose
penetration query failed (distance ``-inf``) gives no row.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["damper_rows", "predicted_rows"]


@compiled
def damper_rows(
    pair: np.ndarray,
    distance_m: np.ndarray,
    gradient: np.ndarray,
    safety_m: float,
    rate_per_s: float,
    columns: np.ndarray,
    num_vars: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``∇dᵀ q̇_0 ≥ -k max(d - d_s, 0)`` with ``k = rate_per_s``: ``C`` ``(k, num_vars)``
    (the gradient on ``columns``, the indices of ``q̇_0``), ``lower`` ``(k,)`` and each row's
    key (its ``pair``), one row per finite distance, and the smallest of them (``inf``
    without one)."""
    rows = 0
    closest = np.inf
    for d in distance_m:
        if math.isfinite(d):
            rows += 1
            closest = min(closest, d)
    c = np.zeros((rows, num_vars))
    lower = np.empty(rows)
    keys = np.empty(rows, dtype=np.int64)
    r = 0
    for k in range(distance_m.size):
        d = distance_m[k]
        if not math.isfinite(d):
            continue
        for j in range(columns.size):
            c[r, columns[j]] = gradient[k, j]
        lower[r] = -rate_per_s * max(d - safety_m, 0.0)
        keys[r] = pair[k]
        r += 1
    return c, lower, keys, closest


@compiled
def predicted_rows(
    state: np.ndarray,
    pair: np.ndarray,
    distance_m: np.ndarray,
    gradient: np.ndarray,
    weights: np.ndarray,
    q_lin: np.ndarray,
    q_base: np.ndarray,
    safety_m: float,
    num_pairs: int,
    block_size: int,
    num_vars: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``∇d(q̄_i)ᵀ Σ_j W_ij q̇_j ≥ min(d_s, d(q)) - d(q̄_i) + ∇d(q̄_i)ᵀ (q̄_i - q_base,i)`` for
    every pair found at a predicted state ``i = state - 1 ≥ 0`` (state 0: the measured
    ``q``, whose distances ``d(q)`` set the floors; ``inf`` for a pair not found there).

    ``q̇_j`` are the variables ``j block_size + (0 … n-1)``. Returns ``C`` ``(k,
    num_vars)``, ``lower`` ``(k,)``, each row's key ``state · num_pairs + pair`` and the
    smallest distance at the measured ``q`` (``inf`` without a pair there)."""
    now = np.full(num_pairs, np.inf)
    closest = np.inf
    rows = 0
    for k in range(state.size):
        if not math.isfinite(distance_m[k]):
            continue
        if state[k] == 0:
            now[pair[k]] = distance_m[k]
            closest = min(closest, distance_m[k])
        else:
            rows += 1
    n, blocks = gradient.shape[1], weights.shape[1]
    c = np.zeros((rows, num_vars))
    lower = np.empty(rows)
    keys = np.empty(rows, dtype=np.int64)
    r = 0
    for k in range(state.size):
        if state[k] == 0 or not math.isfinite(distance_m[k]):
            continue
        keys[r] = state[k] * num_pairs + pair[k]
        i = state[k] - 1
        offset = 0.0
        for col in range(n):
            offset += gradient[k, col] * (q_lin[i, col] - q_base[i, col])
        for j in range(blocks):
            w = weights[i, j]
            if w != 0.0:
                for col in range(n):
                    c[r, j * block_size + col] = w * gradient[k, col]
        lower[r] = min(safety_m, now[pair[k]]) - distance_m[k] + offset
        r += 1
    return c, lower, keys, closest
