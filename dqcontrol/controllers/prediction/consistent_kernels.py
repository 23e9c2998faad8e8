"""The compiled element-wise parts of the consistent prediction (:mod:`.consistent`): the
same numbers as numpy's operations, one by one (the matrix products stay numpy's)."""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["clip_into", "states_into"]


@compiled
def clip_into(values: np.ndarray, low: float, high: float) -> None:
    """``values = np.minimum(np.maximum(values, low), high)`` in place (NaN stays)."""
    for i in range(values.shape[0]):
        v = values[i]
        if v == v:
            v = v if v > low else low
            values[i] = v if v < high else high


@compiled
def states_into(
    q: np.ndarray,
    v0_weights: np.ndarray,
    qd_measured: np.ndarray,
    lagging: bool,
    sigma: float,
    moved: np.ndarray,
    advanced: np.ndarray,
    q_base: np.ndarray,
    sigma_base: np.ndarray,
) -> None:
    """The states of the zero decision and of the linearisation point, in place:
    ``q_base[i] = q`` (plus ``v0_weights[i] qd_measured`` when ``lagging``),
    ``moved[i] = q_base[i] + moved[i]``, ``sigma_base[i] = σ``,
    ``advanced[i] = σ + advanced[i]`` (``moved``, ``advanced``: the products of the
    decision)."""
    for i in range(moved.shape[0]):
        for k in range(moved.shape[1]):
            base = q[k] + v0_weights[i] * qd_measured[k] if lagging else q[k]
            q_base[i, k] = base
            moved[i, k] = base + moved[i, k]
        sigma_base[i] = sigma
        advanced[i] = sigma + advanced[i]
