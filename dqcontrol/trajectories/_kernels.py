"""Compiled loops of the batched targets (private): the same numbers as the numpy
expressions they replace (single operations, no reordered sums), in one call each."""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["circle_rows_into", "value_range"]


@compiled
def value_range(values: np.ndarray) -> tuple[float, float]:
    """``(min, max)`` of a non-empty 1-D array; ``(nan, nan)`` if it holds a NaN."""
    lo = values[0]
    hi = values[0]
    for k in range(values.shape[0]):
        v = values[k]
        if v != v:
            return np.nan, np.nan
        lo = min(lo, v)
        hi = max(hi, v)
    return lo, hi


@compiled
def circle_rows_into(
    cos: np.ndarray, sin: np.ndarray, half_r: float, half_r_omega: float, poses, derivatives
) -> None:
    """The circle's local poses ``[1, 0, 0, 0, 0, h c, h s, 0]`` and derivatives
    ``[0, …, -h' s, h' c, 0]`` ``(N, 8)`` from ``cos``/``sin`` of the angles (every entry
    written)."""
    for i in range(cos.shape[0]):
        for k in range(8):
            poses[i, k] = 0.0
            derivatives[i, k] = 0.0
        poses[i, 0] = 1.0
        poses[i, 5] = half_r * cos[i]
        poses[i, 6] = half_r * sin[i]
        derivatives[i, 5] = -half_r_omega * sin[i]
        derivatives[i, 6] = half_r_omega * cos[i]
