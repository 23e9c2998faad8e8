"""Sums in the order numpy's vectorised loops take them, for compiled code that must give
numpy's numbers bit for bit."""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["lane_dot"]


@compiled
def lane_dot(x: np.ndarray, y: np.ndarray) -> float:
    """``Σ_k x[k] y[k]`` in the order of numpy's ``einsum`` over a contiguous axis: two
    running sums (even and odd ``k``), each block of eight taken from its last pair to its
    first, the rest pair by pair (a missing odd entry adds ``0 · 0``), the two sums added
    last."""
    n = x.shape[0]
    even, odd = 0.0, 0.0
    k = 0
    while n - k >= 8:
        for j in range(3, -1, -1):
            even = x[k + 2 * j] * y[k + 2 * j] + even
            odd = x[k + 2 * j + 1] * y[k + 2 * j + 1] + odd
        k += 8
    while k < n:
        even = x[k] * y[k] + even
        odd = (x[k + 1] * y[k + 1] if k + 1 < n else 0.0 * 0.0) + odd
        k += 2
    return even + odd
