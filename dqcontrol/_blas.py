"""One BLAS thread for the length of a control step.

OpenBLAS hands a product or a factorisation above a few hundred thousand flops to its
thread pool; on a machine whose other cores are busy, waking a second thread costs up to
milliseconds, more than the work. :func:`single_blas_thread` sets every BLAS library loaded
in the process (NumPy's and SciPy's) to one thread and restores the previous counts on
leaving; nested uses cost nothing more. The libraries are found once by ``threadpoolctl``;
an OpenBLAS without OpenMP is then switched through its own ``openblas_get/set_num_threads``
(under a microsecond, where ``threadpoolctl``'s generic calls take a few), any other library
through ``threadpoolctl``. The setting is the process's: BLAS calls from other threads during a
step run on one thread too.

Switching the libraries and back is a few foreign calls, cheap alone but a measurable share
of a 1 kHz step once its caches are cold (docs/performance.md). A loop of steps therefore
holds the context for its whole length (:func:`~dqcontrol.sim.run_loop` does): every step's
own use is then nested and only counts. A caller with its own loop can do the same::

    with single_blas_thread():
        for q in measurements:
            controller.step(q)
"""

from __future__ import annotations

import ctypes
import threading
from collections.abc import Callable
from contextlib import AbstractContextManager

__all__ = ["single_blas_thread"]

_lock = threading.Lock()
_local = threading.local()  # depth: this thread's nested uses
_state: dict = {"switches": None, "depth": 0, "saved": []}

#: The affixes of OpenBLAS's symbols across its builds (plain, SciPy's, 64-bit integers).
_PREFIXES = ("", "scipy_")
_SUFFIXES = ("", "64_", "_64")


def _openblas_switch(lib) -> tuple[Callable[[], int], Callable[[int], None]] | None:
    """``(get, set)`` of an OpenBLAS library's thread count through its own symbols, or
    ``None`` (another library, OpenBLAS on OpenMP, or symbols not found)."""
    if lib.internal_api != "openblas" or getattr(lib, "threading_layer", "") == "openmp":
        return None
    dynlib = getattr(lib, "dynlib", None)
    for prefix in _PREFIXES:
        for suffix in _SUFFIXES:
            get = getattr(dynlib, f"{prefix}openblas_get_num_threads{suffix}", None)
            put = getattr(dynlib, f"{prefix}openblas_set_num_threads{suffix}", None)
            if get is not None and put is not None:
                get.restype, get.argtypes = ctypes.c_int, []
                put.restype, put.argtypes = None, [ctypes.c_int]
                return get, put
    return None


def _switches() -> list[tuple[Callable[[], int], Callable[[int], None]]]:
    """``(get, set)`` of every BLAS library loaded, found at the first call (after loading
    SciPy's, which the steps' factorisations use: a library loaded after this call is
    not switched)."""
    if _state["switches"] is None:
        import scipy.linalg  # noqa: F401 - loads SciPy's BLAS before the libraries are listed
        from threadpoolctl import ThreadpoolController

        found = [lib for lib in ThreadpoolController().lib_controllers if lib.user_api == "blas"]
        _state["switches"] = [
            _openblas_switch(lib) or (lib.get_num_threads, lib.set_num_threads) for lib in found
        ]
    return _state["switches"]


class _SingleThread:
    """The context of :func:`single_blas_thread` (a class: entering and leaving cost less
    than a generator's). A use nested in the same thread only counts, in the thread's own
    count, without the lock."""

    __slots__ = ()

    def __enter__(self) -> None:
        nested = getattr(_local, "depth", 0)
        if nested:
            _local.depth = nested + 1
            return
        with _lock:
            if _state["depth"] == 0:
                switches = _switches()
                _state["saved"] = saved = [get() for get, _ in switches]
                for (_, put), count in zip(switches, saved, strict=True):
                    if count != 1:
                        put(1)
            _state["depth"] += 1
        _local.depth = 1

    def __exit__(self, *exc: object) -> None:
        _local.depth -= 1
        if _local.depth:
            return
        with _lock:
            _state["depth"] -= 1
            if _state["depth"] == 0:
                for (_, put), count in zip(_state["switches"], _state["saved"], strict=True):
                    if count != 1:
                        put(count)


_SINGLE = _SingleThread()


def single_blas_thread() -> AbstractContextManager[None]:
    """Run the ``with`` block with one BLAS thread in every BLAS library loaded (NumPy's,
    SciPy's), the previous counts restored on leaving; a nested use only counts. Every
    controller step runs in it; hold it over a loop of steps so that the steps do not switch
    the libraries one by one (the module's docstring)."""
    return _SINGLE
