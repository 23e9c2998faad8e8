"""The decorator of dqcontrol's compiled kernels: Numba's ``njit`` with its on-disk cache.

Each kernel is compiled on its first call on a machine and loaded from the cache after
that (``__pycache__`` beside the source, or Numba's user cache directory /
``NUMBA_CACHE_DIR`` where the package directory is read-only). Where no cache location is
writable at all, Numba refuses ``cache=True`` when the function is decorated; the kernel
is then compiled in memory in every process instead (slower start, same code).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar, cast

from numba import njit

__all__ = ["compiled"]

F = TypeVar("F", bound=Callable)


def compiled(fn: F) -> F:
    """``numba.njit(cache=True)(fn)``, or ``numba.njit(fn)`` without a writable cache."""
    try:
        return cast(F, njit(cache=True)(fn))  # a dispatcher, called as fn is
    except RuntimeError:  # "cannot cache function …: no locator available"
        return cast(F, njit(fn))
