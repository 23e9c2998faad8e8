"""The decorator of dqcontrol's compiled kernels: Numba's ``njit`` with its on-disk cache.

Each kernel is compiled on its first call on a machine and loaded from the cache after
that (``__pycache__`` beside the source, or Numba's user cache directory /
``NUMBA_CACHE_DIR`` where the package directory is read-only). Where no cache location is
writable at all, Numba refuses ``cache=True`` when the function is decorated; the kernel
is then compiled in memory in every process instead (slower start, same code).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from numba import njit

__all__ = ["compiled"]

F = TypeVar("F", bound=Callable)


def compiled(fn: F) -> F:
    """``numba.njit(cache=True)(fn)``, or ``numba.njit(fn)`` without a writable cache."""
    try:
        return njit(cache=True)(fn)
    except RuntimeError:  # "cannot cache function …: no locator available"
        return njit(fn)
