"""Wall-clock timing of a controller at its period, with the host's own stalls beside it
(docs/theory.md §12.5): what ``dqcontrol bench`` reports for the streamer.

The loop paces sample ``k`` at ``start + k T`` (a sleep, then a poll of the clock), steps
the controller against the ideal kinematic driver, and records when each command was
ready. Unlike :func:`~dqcontrol.sim.loop.run_loop` it does not stop at a missed deadline: it
counts. A separate sleeper thread asks for 0.5 ms sleeps and records how much longer each
took: a stall of the host (another process, the hypervisor) shows there too, so a late
command during a measured stall of ≥ ``HOST_STALL_S`` is counted as the host's.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

from dqcontrol.controllers.base import Controller

__all__ = ["HOST_STALL_S", "WallClockTiming", "time_on_wall_clock"]

#: A sleeper's overrun at least this long is a stall of the host [s].
HOST_STALL_S = 2.5e-3
_SLEEP_S = 5e-4
_SPIN_S = 5e-4


@dataclass(frozen=True)
class WallClockTiming:
    """Figures of one wall-clock run [ms] (``late``: commands later than their period)."""

    samples: int
    late: int
    late_during_host_stalls: int
    lateness_median_ms: float
    lateness_p99_ms: float
    lateness_max_ms: float
    host_stall_p99_ms: float
    host_stall_max_ms: float
    host_stalls: int


class _Sleeper(threading.Thread):
    def __init__(self) -> None:
        super().__init__(name="dqcontrol-sleeper", daemon=True)
        self.stalls: list[tuple[float, float]] = []  # (end time, overrun) [s]
        self.running = True

    def run(self) -> None:
        while self.running:
            t = time.perf_counter()
            time.sleep(_SLEEP_S)
            end = time.perf_counter()
            self.stalls.append((end, end - t - _SLEEP_S))


def time_on_wall_clock(controller: Controller, q0: np.ndarray, seconds: float) -> WallClockTiming:
    """Run ``controller`` (reset at ``q0``) on the wall clock for ``seconds`` against the
    ideal kinematic integration, with a streamed controller's planner in its thread."""
    T = controller.period_s
    controller.reset(q0)
    use = getattr(controller, "use_wall_clock", None)
    if callable(use):
        use(True)
    sleeper = _Sleeper()
    sleeper.start()
    q = np.array(q0, dtype=float)
    ready, num = [], int(round(seconds / T))
    try:
        start = time.perf_counter()
        for k in range(num):
            _sleep_until(start + k * T)
            u = controller.step(q).qd_command
            ready.append(time.perf_counter() - (start + k * T))
            q = q + T * u
            if controller.done:
                break
    finally:
        sleeper.running = False
        close = getattr(controller, "close", None)
        if callable(close):
            close()
        sleeper.join()
    return _figures(np.array(ready), T, start, sleeper.stalls)


def _sleep_until(deadline: float) -> None:
    left = deadline - time.perf_counter() - _SPIN_S
    if left > 0.0:
        time.sleep(left)
    while time.perf_counter() < deadline:
        pass


def _figures(ready_s: np.ndarray, T: float, start: float, stalls) -> WallClockTiming:
    stall = np.array(stalls or [(0.0, 0.0)])
    late = np.flatnonzero(ready_s > T)
    big = stall[stall[:, 1] >= HOST_STALL_S]
    host = 0
    for k in late:  # a late command whose period overlaps a measured stall
        t0, t1 = start + k * T, start + k * T + ready_s[k]
        host += bool(np.any((big[:, 0] >= t0) & (big[:, 0] - big[:, 1] <= t1)))
    ms = 1e3 * ready_s
    return WallClockTiming(
        samples=int(ready_s.size), late=int(late.size), late_during_host_stalls=host,
        lateness_median_ms=float(np.median(ms)), lateness_p99_ms=float(np.percentile(ms, 99)),
        lateness_max_ms=float(np.max(ms)),
        host_stall_p99_ms=float(np.percentile(1e3 * stall[:, 1], 99)),
        host_stall_max_ms=float(1e3 * np.max(stall[:, 1])), host_stalls=int(big.shape[0]),
    )  # fmt: skip
