"""A wall-clock loop's thread in the real-time scheduling class (Linux ``SCHED_FIFO``).

Under the ordinary scheduler a busy host takes the loop's core from it for a time slice of
a few milliseconds whenever another task is runnable there (another process, a thread of
the BLAS library, the planner of a streamed controller): at 1 kHz that is several late
commands. A thread in ``SCHED_FIFO`` runs until it sleeps, ahead of every ordinary task, as
the control loops of real arms do (libfranka asks for it by default). The loop sleeps most
of each period, so the host keeps the rest; Linux keeps 5 % of every second for ordinary
tasks in any case (``kernel.sched_rt_runtime_us``).

It needs the privilege: root, ``CAP_SYS_NICE``, or an ``rtprio`` limit of at least the
priority (``ulimit -r``; ``/etc/security/limits.conf``: ``@realtime - rtprio 99``).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

from dqcontrol.errors import ParameterError

__all__ = ["check_priority", "realtime_priority"]


def check_priority(priority: int | None) -> None:
    """``ParameterError`` unless ``priority`` is ``None`` or a ``SCHED_FIFO`` priority this
    process may take (tried and given back at once)."""
    if priority is None:
        return
    low, high = _bounds()
    if isinstance(priority, bool) or not isinstance(priority, int) or not low <= priority <= high:
        raise ParameterError(
            f"realtime_priority must be an integer in [{low}, {high}] (or None), got {priority!r}"
        )
    with realtime_priority(priority):
        pass


@contextlib.contextmanager
def realtime_priority(priority: int | None) -> Iterator[None]:
    """The calling thread in ``SCHED_FIFO`` at ``priority`` for the block, its scheduling
    given back after; ``None``: left alone.

    Raises:
        ParameterError: not Linux, or the process lacks the privilege (the message says
            how to grant it).
    """
    if priority is None:
        yield
        return
    if not hasattr(os, "SCHED_FIFO"):
        raise ParameterError("realtime_priority needs Linux's SCHED_FIFO scheduling class")
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError as exc:
        raise ParameterError(
            f"realtime_priority={priority}: this process may not use the real-time scheduling "
            f"class ({exc.strerror}); run it with CAP_SYS_NICE or an rtprio limit of at least "
            f"{priority} (ulimit -r), or leave realtime_priority at None"
        ) from exc
    try:
        yield
    finally:
        os.sched_setscheduler(0, policy, param)


def _bounds() -> tuple[int, int]:
    if not hasattr(os, "SCHED_FIFO"):
        return 1, 99
    return os.sched_get_priority_min(os.SCHED_FIFO), os.sched_get_priority_max(os.SCHED_FIFO)
