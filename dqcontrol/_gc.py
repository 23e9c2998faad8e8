"""The garbage collector kept to young objects while a real-time loop runs.

A full collection walks every object of the process: with Pinocchio, MuJoCo, the solvers
and their Python wrappers loaded that is hundreds of thousands, tens of milliseconds, at a
moment the collector picks. :func:`young_gc_only` makes one full collection before the
loop and freezes what survives (``gc.freeze``): the collections during the loop then see
only the objects made in it. A control loop (:func:`~dqcontrol.sim.run_loop` on the wall
clock), the sim-server and a streamed controller's planner process hold it while they run.
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator

__all__ = ["young_gc_only"]


@contextlib.contextmanager
def young_gc_only(enabled: bool = True) -> Iterator[None]:
    """While the block runs, the garbage collector sees only objects made in it: a full
    collection first, then every existing object frozen (``gc.freeze``), unfrozen after
    (unless the caller had frozen objects already: ``gc.unfreeze`` would free theirs too).
    ``enabled=False``: the collector is left alone."""
    if not enabled:
        yield
        return
    frozen_before = gc.get_freeze_count()
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        if frozen_before == 0:
            gc.unfreeze()
