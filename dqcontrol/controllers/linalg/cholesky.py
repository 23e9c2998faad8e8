"""A compiled Cholesky factorisation for small dense matrices, with its own test of
positive definiteness (the levels' solves, the singularity check): below a few dozen rows
LAPACK's call costs more than the factorisation."""

from __future__ import annotations

import math

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["cholesky_above", "cholesky_into"]


@compiled
def cholesky_into(a: np.ndarray, out: np.ndarray, share: float, shift: float = 0.0) -> bool:
    """``out`` = the lower Cholesky factor of ``a - shift I`` (``a`` symmetric; only its
    lower triangle is read, and ``out`` may be ``a`` itself); False when a squared pivot
    is not above ``share`` times the largest diagonal entry of ``a`` (or is NaN)."""
    scale = 0.0
    for i in range(a.shape[0]):
        scale = max(scale, a[i, i])
    return cholesky_above(a, out, share * scale, shift)


@compiled
def cholesky_above(a: np.ndarray, out: np.ndarray, threshold: float, shift: float) -> bool:
    """:func:`cholesky_into` with every squared pivot above ``threshold`` (not NaN)."""
    n = a.shape[0]
    for j in range(n):
        s = a[j, j] - shift
        for k in range(j):
            s -= out[j, k] * out[j, k]
        if not s > threshold:
            return False
        d = math.sqrt(s)
        out[j, j] = d
        for i in range(j + 1, n):
            t = a[i, j]
            for k in range(j):
                t -= out[i, k] * out[j, k]
            out[i, j] = t / d
    return True
