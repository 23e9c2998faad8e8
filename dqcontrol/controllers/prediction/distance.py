"""The largest joint-wise distance between two vectors, compiled (one call instead of
numpy's subtraction, absolute value and maximum: the same number, a maximum being exact)."""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["max_abs_difference"]


@compiled
def max_abs_difference(a: np.ndarray, b: np.ndarray) -> float:
    """``max |a - b|`` over the entries of two 1-D arrays of the same length (NaN if a
    difference is NaN, as ``np.max``; ``-inf`` for empty arrays)."""
    out = -np.inf
    for k in range(a.shape[0]):
        d = abs(a[k] - b[k])
        if d > out or d != d:
            out = d
            if d != d:
                return d
    return out
