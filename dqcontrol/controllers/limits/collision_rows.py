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
def _braked_floor(safety_m: float, now_m: float, approach: float, braking: float, t_s: float):
    """``min(d_s, d(q) - u(t))``: ``u(t)`` the approach still made by ``t`` when the pair
    closes at ``approach`` [m/s] now and that rate is braked at ``braking`` [m/s²]
    (``v t - b t²/2`` until it stops at ``v/b``, ``v²/2b`` after); none when not closing."""
    if approach <= 0.0 or braking <= 0.0:
        return min(safety_m, now_m)
    if t_s * braking < approach:
        unavoidable = approach * t_s - 0.5 * braking * t_s * t_s
    else:
        unavoidable = 0.5 * approach * approach / braking
    return min(safety_m, now_m - unavoidable)


@compiled
def _pairs_now(state, pair, distance_m, gradient, motion, num_pairs):
    """Each pair's distance at the measured state (``inf``: not found there), its closing
    rate ``-∇dᵀ q̇`` and the rate at which the bound can brake it ``share Σ_k |∇d_k|
    a_k`` (``motion``: ``(q̇, a_max, share)``), and the smallest distance."""
    qd, a_max, share = motion
    now = np.full(num_pairs, np.inf)
    approach, braking = np.zeros(num_pairs), np.zeros(num_pairs)
    closest = np.inf
    for k in range(state.size):
        if state[k] != 0 or not math.isfinite(distance_m[k]):
            continue
        now[pair[k]] = distance_m[k]
        closest = min(closest, distance_m[k])
        rate, brake = 0.0, 0.0
        for col in range(qd.size):
            rate -= gradient[k, col] * qd[col]
            brake += abs(gradient[k, col]) * a_max[col]
        approach[pair[k]], braking[pair[k]] = rate, share * brake
    return now, approach, braking, closest


@compiled
def predicted_rows(
    state: np.ndarray,
    pair: np.ndarray,
    distance_m: np.ndarray,
    gradient: np.ndarray,
    prediction: tuple,
    motion: tuple,
    safety_m: float,
    num_pairs: int,
    block_size: int,
    num_vars: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``∇d(q̄_i)ᵀ Σ_j W_ij q̇_j ≥ f_i - d(q̄_i) + ∇d(q̄_i)ᵀ (q̄_i - q_base,i)`` for every
    pair found at a predicted state ``i = state - 1 ≥ 0`` (state 0: the measured ``q``).
    The floor ``f_i = min(d_s, d(q) - u_i)`` is the safety distance, or for a pair inside
    or about to reach it the distance it is at now less the approach it cannot avoid by the
    state's time ``t_i`` braking at the bound (:func:`_braked_floor`; ``d(q) = inf`` for a
    pair not found at ``q``).

    ``prediction`` is ``(W, q̄, q_base, t)`` (``t`` ``(p,)``: each state's time [s]),
    ``motion`` ``(q̇, a_max, share)``: the velocity now, the acceleration bound and the
    share of it the floors count on. ``q̇_j`` are the variables ``j block_size + (0 …
    n-1)``. Returns ``C`` ``(k, num_vars)``, ``lower`` ``(k,)``, each row's key ``state ·
    num_pairs + pair`` and the smallest distance at the measured ``q`` (``inf`` without a
    pair there)."""
    weights, q_lin, q_base, times = prediction
    now, approach, braking, closest = _pairs_now(
        state, pair, distance_m, gradient, motion, num_pairs
    )
    rows = 0
    for k in range(state.size):
        if state[k] != 0 and math.isfinite(distance_m[k]):
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
        i, g = state[k] - 1, pair[k]
        offset = 0.0
        for col in range(n):
            offset += gradient[k, col] * (q_lin[i, col] - q_base[i, col])
        for j in range(blocks):
            w = weights[i, j]
            if w != 0.0:
                for col in range(n):
                    c[r, j * block_size + col] = w * gradient[k, col]
        floor = _braked_floor(safety_m, now[g], approach[g], braking[g], times[i])
        lower[r] = floor - distance_m[k] + offset
        r += 1
    return c, lower, keys, closest
