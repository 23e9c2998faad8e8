"""Prediction instants and the integration of the previous horizon (docs/theory.md §4.2).

The predictive controller solves for commands ``qd_i`` at the instants
``τ_i = τ_p (i-1)² / (p-1)²`` (thesis eq. 3.15). To predict ``q(t + τ_i)`` it takes the
previous step's solution as a piecewise-linear function of time through
``(τ_j, qd_j)``, shifted by one period ``T`` (the previous solution was computed at
``t - T``), held at its last value past the horizon, and integrates it from the measured
``q(t)`` (thesis §3.3.3). For fixed ``τ`` and ``T`` that integral is linear in the previous
values, so it is one constant ``p × p`` matrix ``W``:

    q̂_i = q(t) + Σ_j W[i, j] qd_j^prev,     σ̂_i = σ(t) + Σ_j W[i, j] s_j^prev.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.errors import ParameterError

__all__ = ["integration_matrix", "interpolation_matrix", "prediction_instants"]


def prediction_instants(count: int, horizon_s: float) -> np.ndarray:
    """``τ_i = τ_p (i-1)²/(p-1)²`` for ``i = 1..p`` [s] (parabolic spacing, eq. 3.15)."""
    if int(count) != count or count < 2:
        raise ParameterError(f"number of prediction instants p must be an integer ≥ 2, got {count}")
    if not np.isfinite(horizon_s) or horizon_s <= 0.0:
        raise ParameterError(f"prediction horizon tau_p must be > 0 s, got {horizon_s}")
    i = np.arange(count, dtype=float)
    return horizon_s * i**2 / (count - 1) ** 2


def _antiderivative_weights(tau: np.ndarray, x: float) -> np.ndarray:
    """Weights ``c`` with ``∫_0^x g(τ) dτ = c · v`` for ``g`` piecewise linear through
    ``(τ_j, v_j)`` and held at ``v_p`` after ``τ_p`` (``τ_0 = 0``)."""
    p = tau.size
    c = np.zeros(p)
    for j in range(p - 1):
        a, b = tau[j], tau[j + 1]
        if x <= a:
            break
        h = b - a
        u = min(x, b) - a  # length covered inside [a, b]
        # ∫_a^{a+u} (v_j (1 - s/h) + v_{j+1} s/h) ds
        c[j] += u - u * u / (2.0 * h)
        c[j + 1] += u * u / (2.0 * h)
    if x > tau[-1]:
        c[-1] += x - tau[-1]
    return c


def integration_matrix(tau: np.ndarray, period_s: float) -> np.ndarray:
    """``W`` (p×p) with ``q̂_i - q(t) = Σ_j W[i, j] v_j``: the previous profile ``v`` shifted by
    ``period_s`` and integrated over ``[0, τ_i]``."""
    tau = np.asarray(tau, dtype=float)
    shift = float(period_s)
    w = np.empty((tau.size, tau.size))
    start = _antiderivative_weights(tau, shift)
    for i, ti in enumerate(tau):
        w[i] = _antiderivative_weights(tau, ti + shift) - start
    return w


def interpolation_matrix(tau: np.ndarray, shift_s: float) -> np.ndarray:
    """``S`` with ``(S v)_i = g(τ_i + shift)``, ``g`` piecewise linear through ``(τ_j, v_j)``
    and held at its ends: the previous horizon shifted by one period (a warm start)."""
    p = tau.size
    out = np.zeros((p, p))
    for i, t in enumerate(tau + shift_s):
        if t >= tau[-1]:
            out[i, -1] = 1.0
            continue
        j = int(np.searchsorted(tau, t, side="right")) - 1
        h = tau[j + 1] - tau[j]
        frac = (t - tau[j]) / h
        out[i, j] = 1.0 - frac
        out[i, j + 1] = frac
    return out
