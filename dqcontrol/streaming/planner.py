"""The planner: the path-following controller run at its own period ``T_p`` from the latest
measurement projected to the plan's start by the stream already committed (docs/theory.md
§12.1), in the caller's thread (stepped mode), or on the wall clock in a process of its
own (the default: measured, docs/theory.md §12.5) or a thread.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import time
from dataclasses import dataclass

import numpy as np

from dqcontrol._blas import single_blas_thread
from dqcontrol._gc import young_gc_only
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.streaming.plan import Plan, plan_from_result
from dqcontrol.streaming.streamer import Streamer

__all__ = [
    "PlanRequest",
    "Planner",
    "PlannerProcess",
    "PlannerThread",
    "choose_plan_period",
    "project",
]


@dataclass(frozen=True)
class PlanRequest:
    """What a plan is solved from.

    Attributes:
        plan_id: the plan's number. start_k: the stream sample it will start at.
        made_s: stream time of the measurement [s].
        q: the measured joint positions plus the committed stream's displacement up to
            ``start_k`` [rad]. qd: the measured velocities (``None`` with a lead: the
            committed command is then the controller's velocity at the start).
        sigma: the stream's phase at ``start_k`` [s]. qd_prev: the stream's command just
            before ``start_k`` [rad/s].
    """

    plan_id: int
    start_k: int
    made_s: float
    q: np.ndarray
    qd: np.ndarray | None
    sigma: float
    qd_prev: np.ndarray


def project(
    streamer: Streamer,
    q_measured: np.ndarray,
    qd_measured: np.ndarray,
    lead_k: int,
    plan_id: int,
    lag_s: float = 0.0,
) -> PlanRequest:
    """The request of a plan starting ``lead_k`` samples after the streamer's present one:
    a copy of the streamer run ahead gives the commands up to there, its phase and last
    command. The arm is moved by those commands from the measurement: behind a velocity
    servo of time constant ``lag_s`` as a first-order lag from the measured velocity
    (docs/theory.md §8.7), which is then the velocity the plan starts from."""
    k, T = streamer.k, streamer.period_s
    if lead_k == 0:
        sigma = streamer.plan.phase(streamer.tau_s) if streamer.plan else streamer.sigma0
        return PlanRequest(
            plan_id, k, k * T, q_measured, qd_measured, sigma, streamer.tracker.u.copy()
        )
    twin = streamer.copy()
    q = np.array(q_measured, dtype=float)
    v = np.array(qd_measured, dtype=float)
    e = np.exp(-T / lag_s) if lag_s > 0.0 else 0.0
    c = lag_s * (1.0 - e)
    sample = None
    for _ in range(lead_k):
        sample = twin.step()
        q += (T - c) * sample.u + c * v
        v = e * v + (1.0 - e) * sample.u
    assert sample is not None
    qd = v if lag_s > 0.0 else None
    return PlanRequest(plan_id, k + lead_k, k * T, q, qd, sample.sigma_next, sample.u.copy())


class Planner:
    """One plan per request from ``controller`` (whose ``period_s`` is ``T_p``).

    ``step_times_s`` holds the controller's step time of every plan.
    """

    def __init__(self, controller: PathFollowingController) -> None:
        self.controller = controller
        self.durations_s = np.array(controller.layout.durations_s, dtype=float)
        #: the servo lag the controller predicts (0: none), for the projection
        self.lag_s = float(controller.prediction_model.lag_s)
        self.step_times_s: list[float] = []

    def plan(self, request: PlanRequest, fresh: bool = False, stop: bool = False) -> Plan:
        """Solve one step of the controller from the request's state; its plan. ``fresh``:
        the controller is first reset there (its memory of the last plan is not of this
        run: a stream taking over another controller's). ``stop``: the controller's stop
        is requested first (it then keeps stopping: docs/theory.md §8.10)."""
        c = self.controller
        if fresh:
            c.reset(np.array(request.q, dtype=float), request.qd_prev, request.sigma)
        if stop and not c.stopping:
            c.request_stop()
        c.sigma, c.qd_prev = request.sigma, np.array(request.qd_prev, dtype=float)
        start = time.perf_counter()
        result = c.step(np.array(request.q, dtype=float), request.qd)
        self.step_times_s.append(time.perf_counter() - start)
        return plan_from_result(
            result, self.durations_s, plan_id=request.plan_id, start_k=request.start_k,
            made_s=request.made_s, q_start=request.q,
        )  # fmt: skip


class PlannerThread:
    """A :class:`Planner` in a daemon thread: :meth:`request` hands it a request (refused
    while it is still solving the last one), :meth:`take` returns a finished plan or
    ``None``; neither waits. ``gate`` (set by default) can be cleared to make the planner
    stop answering (a test of the play-out)."""

    def __init__(self, planner: Planner) -> None:
        self.planner = planner
        self.gate = threading.Event()
        self.gate.set()
        self._wake = threading.Event()
        self._lock = threading.Lock()
        self._request: tuple | None = None
        self._done: Plan | None = None
        self._busy = False
        self._closed = False
        self.busy_skips = 0
        self.error = ""
        self._thread = threading.Thread(target=self._run, name="dqcontrol-planner", daemon=True)
        self._thread.start()

    def request(
        self,
        stream: Streamer,
        q: np.ndarray,
        qd: np.ndarray,
        lead_k: int,
        plan_id: int,
        fresh: bool = False,
        stop: bool = False,
    ) -> bool:
        """Solve a plan from the measurement ``q``, ``qd`` and ``stream`` (a copy of the
        streamer, projected ahead by ``lead_k`` samples in the planner's thread); ``fresh``
        and ``stop`` as in :meth:`Planner.plan`."""
        with self._lock:
            if self._busy:
                self.busy_skips += 1
                return False
            self._busy = True
            lag = self.planner.lag_s
            self._request = (stream, q.copy(), qd.copy(), lead_k, plan_id, lag, fresh, stop)
        self._wake.set()
        return True

    def take(self) -> Plan | None:
        """The plan finished since the last call, or ``None``."""
        if self._done is None:
            return None
        with self._lock:
            plan, self._done = self._done, None
        return plan

    def pause(self) -> None:
        """Block the planner before its next plan: it stops answering."""
        self.gate.clear()

    def close(self) -> None:
        """End the thread (a blocked planner is released first)."""
        self._closed = True
        self.gate.set()
        self._wake.set()
        self._thread.join(timeout=5.0)

    def _run(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()
            if self._closed:
                return
            self.gate.wait()
            request = self._request
            if request is None or self._closed:
                continue
            try:
                plan = self.planner.plan(project(*request[:-2]), *request[-2:])
            except Exception as exc:  # noqa: BLE001 - reported; the streamer plays out
                self.error = f"{type(exc).__name__}: {exc}"
                return
            with self._lock:
                self._done, self._busy = plan, False


class PlannerProcess:
    """A :class:`Planner` in a process of its own (forked with the controller's state):
    the same :meth:`request`/:meth:`take` as :class:`PlannerThread`, through a pipe, so
    that the planner's compiled code and solver, which hold the interpreter's lock while
    they run, never hold up the streamer (docs/theory.md §12.5). :meth:`pause` stops the
    process (a test of the play-out); :meth:`close` ends it."""

    def __init__(self, planner: Planner) -> None:
        ctx = multiprocessing.get_context("fork")
        self.planner = planner
        self._conn, child = ctx.Pipe()
        self._process = ctx.Process(
            target=_serve, args=(planner, child), name="dqcontrol-planner", daemon=True
        )
        self._process.start()
        child.close()
        self._busy = False
        self._done: Plan | None = None
        self.busy_skips = 0
        self.error = ""

    def request(
        self,
        stream: Streamer,
        q: np.ndarray,
        qd: np.ndarray,
        lead_k: int,
        plan_id: int,
        fresh: bool = False,
        stop: bool = False,
    ) -> bool:
        """As :meth:`PlannerThread.request`."""
        if not self._collect() or self.error:
            self.busy_skips += 1
            return False
        try:
            self._conn.send((stream, q, qd, lead_k, plan_id, self.planner.lag_s, fresh, stop))
        except OSError as exc:
            self.error = f"the planner process is gone ({exc})"
            return False
        self._busy = True
        return True

    def take(self) -> Plan | None:
        """The plan finished since the last call, or ``None``."""
        self._collect()
        plan, self._done = self._done, None
        return plan

    def warm_up(
        self,
        stream: Streamer,
        q: np.ndarray,
        qd: np.ndarray,
        count: int,
        timeout_s: float,
        stop: bool = False,
    ) -> list[float]:
        """Plan ``count`` times for the request of a plan starting now, each plan waited for
        (at most ``timeout_s`` in all) and dropped: the forked process's first plans touch
        its copied memory and caches for the first time and take several times a plan's
        usual time, which must not fall on the clock. With ``stop`` the plans are the
        stop's from a fresh reset (for a stream that is only reset when it takes over).
        Returns the plans' times [s]."""
        times: list[float] = []
        deadline = time.perf_counter() + timeout_s
        for _ in range(count):
            start = time.perf_counter()
            if not self.request(stream, q, qd, 0, 0, fresh=stop, stop=stop):
                break
            if not self._conn.poll(max(deadline - time.perf_counter(), 0.0)):
                return times  # still busy: its plan is collected (and used) later
            self._collect()
            self._done = None
            self.planner.step_times_s.pop()
            times.append(time.perf_counter() - start)
        return times

    def pause(self) -> None:
        """Stop the process where it is (``SIGSTOP``): the planner stops answering."""
        if self._process.pid is not None:
            os.kill(self._process.pid, signal.SIGSTOP)

    def close(self) -> None:
        """End the process (killed if it does not end within a second)."""
        with contextlib.suppress(OSError):
            self._conn.send(None)
        self._process.join(timeout=1.0)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(timeout=1.0)
        self._conn.close()

    def _collect(self) -> bool:
        """Receive a finished plan if one is there; whether the planner is free."""
        if not self._busy or not self._conn.poll():
            return not self._busy
        try:
            message = self._conn.recv()
        except (EOFError, OSError):
            self.error = "the planner process ended"
            return False
        if isinstance(message, str):
            self.error = message
            return False
        self._done, step_s = message
        self.planner.step_times_s.append(step_s)
        self._busy = False
        return True


#: The shortest plan period :func:`choose_plan_period` gives [s]: the planner process is
#: slower than a step timed in the caller's process (its lower priority, the request and
#: the plan through a pipe), by about a millisecond on a 2-core host at 1 kHz.
MIN_PLAN_PERIOD_S = 0.005

#: How much lower the planner process's priority is than the streamer's (``nice``).
PLANNER_NICENESS = 10


def _serve(planner: Planner, conn) -> None:
    """The planner process: a plan for every request until ``None`` or the pipe closes,
    with one BLAS thread and the garbage collector kept to young objects for its whole life
    (as a control loop holds them: a full collection would make a plan late), at a lower
    priority than the streamer's (:data:`PLANNER_NICENESS`): on a busy host the scheduler
    then takes its time from the planner, which has a plan period to spare, not from the
    streamer, which has one command period."""
    with contextlib.suppress(OSError):
        os.nice(PLANNER_NICENESS)
    with single_blas_thread(), young_gc_only():
        _answer(planner, conn)


def _answer(planner: Planner, conn) -> None:
    """A plan for every request on ``conn`` until ``None`` or the pipe closes."""
    while True:
        try:
            request = conn.recv()
        except (EOFError, OSError):
            return
        if request is None:
            return
        try:
            plan = planner.plan(project(*request[:-2]), *request[-2:])
        except Exception as exc:  # noqa: BLE001 - reported; the streamer plays out
            conn.send(f"{type(exc).__name__}: {exc}")
            return
        conn.send((plan, planner.step_times_s[-1]))


def choose_plan_period(
    step_times_s, period_s: float, margin: float = 2.0, floor_s: float = MIN_PLAN_PERIOD_S
) -> float:
    """The shortest plan period [s] that is a whole multiple of ``period_s``, at least
    ``margin`` times the 99th percentile of the measured planner ``step_times_s`` and at
    least ``floor_s``."""
    p99 = float(np.percentile(np.asarray(step_times_s, dtype=float), 99))
    shortest = max(margin * p99, floor_s)
    return max(1, int(np.ceil(shortest / period_s - 1e-9))) * period_s
