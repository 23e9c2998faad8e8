"""The planner: the path-following controller run at its own period ``T_p`` from the latest
measurement projected to the plan's start by the stream already committed (docs/theory.md
§12.1), in the caller's thread (stepped mode) or a thread of its own (wall clock).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.streaming.plan import Plan, plan_from_result
from dqcontrol.streaming.streamer import Streamer

__all__ = ["PlanRequest", "Planner", "PlannerThread", "project"]


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
    streamer: Streamer, q_measured: np.ndarray, qd_measured: np.ndarray, lead_k: int, plan_id: int
) -> PlanRequest:
    """The request of a plan starting ``lead_k`` samples after the streamer's present one:
    a copy of the streamer run ahead gives the displacement, phase and last command there."""
    k, T = streamer.k, streamer.period_s
    if lead_k == 0:
        sigma = streamer.plan.phase(streamer.tau_s) if streamer.plan else streamer.sigma0
        return PlanRequest(
            plan_id, k, k * T, q_measured, qd_measured, sigma, streamer.tracker.u.copy()
        )
    twin = streamer.copy()
    q0 = twin.q.copy()
    sample = None
    for _ in range(lead_k):
        sample = twin.step()
    assert sample is not None
    q = q_measured + (twin.q - q0)
    return PlanRequest(plan_id, k + lead_k, k * T, q, None, sample.sigma_next, sample.u.copy())


class Planner:
    """One plan per request from ``controller`` (whose ``period_s`` is ``T_p``).

    ``step_times_s`` holds the controller's step time of every plan.
    """

    def __init__(self, controller: PathFollowingController) -> None:
        self.controller = controller
        self.durations_s = np.array(controller.layout.durations_s, dtype=float)
        self.step_times_s: list[float] = []

    def plan(self, request: PlanRequest) -> Plan:
        """Solve one step of the controller from the request's state; its plan."""
        c = self.controller
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
        self, stream: Streamer, q: np.ndarray, qd: np.ndarray, lead_k: int, plan_id: int
    ) -> bool:
        """Solve a plan from the measurement ``q``, ``qd`` and ``stream`` (a copy of the
        streamer, projected ahead by ``lead_k`` samples in the planner's thread)."""
        with self._lock:
            if self._busy:
                self.busy_skips += 1
                return False
            self._busy = True
            self._request = (stream, q.copy(), qd.copy(), lead_k, plan_id)
        self._wake.set()
        return True

    def take(self) -> Plan | None:
        """The plan finished since the last call, or ``None``."""
        if self._done is None:
            return None
        with self._lock:
            plan, self._done = self._done, None
        return plan

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
                plan = self.planner.plan(project(*request))
            except Exception as exc:  # noqa: BLE001 - reported; the streamer plays out
                self.error = f"{type(exc).__name__}: {exc}"
                return
            with self._lock:
                self._done, self._busy = plan, False
