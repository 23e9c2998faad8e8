"""One BLAS thread for the length of a control step.

OpenBLAS hands a product or a factorisation above a few hundred thousand flops to its
thread pool; on a machine whose other cores are busy, waking a second thread costs up to
milliseconds, more than the work. :func:`single_blas_thread` sets every BLAS library loaded
in the process to one thread (through ``threadpoolctl``, a few microseconds) and restores
the previous counts on leaving; nested uses cost nothing more. The setting is the
process's: BLAS calls from other threads during a step run on one thread too.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["single_blas_thread"]

_lock = threading.Lock()
_state: dict = {"libraries": None, "depth": 0, "saved": []}


def _libraries() -> list:
    if _state["libraries"] is None:
        from threadpoolctl import ThreadpoolController

        found = ThreadpoolController().lib_controllers
        _state["libraries"] = [lib for lib in found if lib.user_api == "blas"]
    return _state["libraries"]


@contextmanager
def single_blas_thread() -> Iterator[None]:
    """Run the ``with`` block with one BLAS thread."""
    with _lock:
        if _state["depth"] == 0:
            libraries = _libraries()
            _state["saved"] = [lib.num_threads for lib in libraries]
            for lib in libraries:
                lib.set_num_threads(1)
        _state["depth"] += 1
    try:
        yield
    finally:
        with _lock:
            _state["depth"] -= 1
            if _state["depth"] == 0:
                for lib, count in zip(_state["libraries"], _state["saved"], strict=True):
                    lib.set_num_threads(count)
