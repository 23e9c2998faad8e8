"""A path-following controller planning at ``T_p`` and streamed at ``T``: one
:class:`~dqcontrol.controllers.base.Controller` to every loop (docs/theory.md §12).

:func:`streamed` wraps a :class:`~dqcontrol.controllers.path_following.controller.
PathFollowingController` built with ``period_s = T_p`` (its first interval is then one plan
period). In stepped mode (simulated time) the plans are solved in the caller's thread at
every ``T_p``-th sample, deterministically; with ``lead_periods = 0`` a plan starts at the
sample of its measurement (a solve takes no simulated time, as in the synchronous loop),
otherwise ``lead_periods`` later, from the measurement projected there. On the wall clock
(:meth:`StreamedController.use_wall_clock`) a planner thread solves while the streamer
sends, and a plan starts one plan period after its measurement.
"""

from __future__ import annotations

import copy
import sys
import time
from dataclasses import dataclass
from typing import cast

import numpy as np

from dqcontrol.controllers.base import (
    Controller,
    StepDiagnostics,
    StepResult,
    check_positive,
    per_joint,
)
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.errors import ParameterError
from dqcontrol.streaming.planner import Planner, PlannerProcess, PlannerThread, project
from dqcontrol.streaming.streamer import Streamer, StreamSample
from dqcontrol.streaming.tracker import JerkLimitedTracker

__all__ = ["StreamDiagnostics", "StreamedController", "streamed"]

#: The interpreter's thread switch interval while a planner thread runs [s].
SWITCH_INTERVAL_S = 5e-5
#: At the task's end the stream follows its plans until its command and the plan's first
#: are below this [rad/s], or for at most :data:`SETTLE_PLANS` plan periods.
SETTLED_RAD_S, SETTLE_PLANS = 1e-3, 20
#: Plans a planner process makes (and drops) before the clock starts, and the longest wait
#: for them [s] (docs/theory.md §12.5).
WARM_UP_PLANS, WARM_UP_TIMEOUT_S = 3, 10.0


@dataclass(frozen=True)
class StreamDiagnostics(StepDiagnostics):
    """:class:`StepDiagnostics` of a streamed period, with the plan it came from and its
    age [s] (time since the plan's measurement)."""

    plan_id: int = 0
    plan_age_s: float = 0.0
    lateness_s: float = float("nan")


def _plan_periods(planner: Controller, period_s: float) -> int:
    """``T_p / T`` as an integer ≥ 1, or a :class:`ParameterError`."""
    if not isinstance(planner, PathFollowingController):
        raise ParameterError(
            f"the streamer needs a controller with a consistent plan (path_following); "
            f"{getattr(planner, 'name', type(planner).__name__)!r} predicts from its "
            "previous plan, so its horizon is not a trajectory the arm can follow: run it "
            "synchronously"
        )
    T = check_positive("period_s (T)", period_s, "s")
    T_p = planner.period_s
    ratio = T_p / T
    num = round(ratio)
    if num < 1 or abs(ratio - num) > 1e-9 * max(ratio, 1.0):
        raise ParameterError(
            f"the plan period T_p = {T_p:g} s must be a whole multiple ≥ 1 of the stream "
            f"period T = {T:g} s (e.g. {max(num, 1) * T:g} s)"
        )
    return num


class StreamedController(Controller):
    """See :func:`streamed`."""

    def __init__(
        self,
        planner: PathFollowingController,
        period_s: float,
        *,
        acceleration_max=None,
        jerk_max=None,
        lead_periods: int = 0,
        patience_plans: int = 2,
        feedback_s: float | None = None,
        planner_in: str = "process",
    ) -> None:
        num = _plan_periods(planner, period_s)
        super().__init__(planner.robot, planner.task, period_s)
        self.planner_controller, self.plan_periods = planner, num
        self.plan_period_s = planner.period_s
        self.name = f"{planner.name}_streamed"
        lim = planner.robot.limits
        self.qd_max = np.array(planner.qd_max, dtype=float)  # the bound the plans keep
        self.qdd_max = _limit(
            "acceleration_max", acceleration_max, _default_acceleration(planner), self.n
        )
        self.qddd_max = _limit("jerk_max", jerk_max, cast(np.ndarray, lim.qddd_max), self.n)
        self.a_const = self.qdd_max if np.all(np.isfinite(self.qdd_max)) else None
        if lead_periods not in (0, num):
            raise ParameterError(
                f"lead_periods must be 0 or the plan period in samples ({num}), got "
                f"{lead_periods!r}"
            )
        self.lead_periods = int(lead_periods)
        if planner_in not in ("process", "thread"):
            raise ParameterError(f"planner_in must be 'process' or 'thread', got {planner_in!r}")
        self.planner_in = planner_in
        tracker = JerkLimitedTracker(self.qd_max, self.qdd_max, self.qddd_max, self.period_s)
        feedback = 2.0 * self.plan_period_s if feedback_s is None else feedback_s
        feedback = check_positive("feedback_s", feedback, "s")
        self.streamer = Streamer(tracker, feedback, num * (1 + int(patience_plans)))
        self.planner = Planner(planner)
        self._thread: PlannerThread | PlannerProcess | None = None
        self._wall_clock = False
        self._next_id = 1
        self.streamer_times_s: list[float] = []
        self.ages_s: list[float] = []
        self.lateness_s: list[float] = []
        self._t0: float | None = None
        self._thread_stats: dict = {}
        self.first_plan_s = 0.0
        #: the planner process's warm-up plans' times [s] (none in stepped mode)
        self.warm_up_s: list[float] = []
        self._start_state = (np.zeros(self.n), np.zeros(self.n))
        #: the command sent the period before the last [rad/s]: a stop's jerk rows start
        #: from it
        self.qd_before_prev = np.zeros(self.n)
        self._clear_requests()

    def _clear_requests(self) -> None:
        """No plan to reset for, no stop asked or owed, the task's end not reached."""
        #: the next plan resets the planner's controller first (:meth:`take_over`)
        self._fresh = False
        #: a stop was requested and no plan asked for since (:meth:`_begin_stop`)
        self._stop_unasked = False
        #: the plans asked for are the planner's stop (:meth:`_begin_stop`)
        self._stop_plans = False
        #: the stream's sample at which the phase first reached the task's end
        self._end_k: int | None = None

    # ------------------------------------------------------------------ modes
    def use_wall_clock(self, on: bool) -> None:
        """Plan in a thread of its own, each plan one plan period after its measurement
        (``on``), or in the caller's thread (stepped: deterministic)."""
        self._wall_clock = bool(on)
        if on and self._thread is None and self._reset_done:
            kind = PlannerProcess if self.planner_in == "process" else PlannerThread
            self._thread, self._t0 = kind(self.planner), None
            if isinstance(self._thread, PlannerProcess):
                start = self._start_state
                self.warm_up_s = self._thread.warm_up(
                    self.streamer.copy(), start[0], start[1], WARM_UP_PLANS, WARM_UP_TIMEOUT_S
                )
            # other threads (a planner thread, the run log's writer) run Python: hand the
            # interpreter back to the streamer within SWITCH_INTERVAL_S, not the 5 ms default
            self._switch_before = sys.getswitchinterval()
            sys.setswitchinterval(SWITCH_INTERVAL_S)

    def warm_up_stop(self, count: int = WARM_UP_PLANS) -> None:
        """On the wall clock, ``count`` stop plans from a fresh reset made and dropped by the
        planner process before the clock: a stream that takes over another controller (and
        is reset by it) would otherwise solve its first stop cold."""
        if isinstance(self._thread, PlannerProcess):
            start = self._start_state
            self.warm_up_s += self._thread.warm_up(
                self.streamer.copy(), start[0], start[1], count, WARM_UP_TIMEOUT_S, stop=True
            )

    def close(self) -> None:
        """Stop the planner thread (if any)."""
        if self._thread is not None:
            sys.setswitchinterval(self._switch_before)
            self._thread.close()
            self._thread_stats = {
                "planner_busy_skips": self._thread.busy_skips,
                "planner_error": self._thread.error,
            }
            self._thread = None

    def __deepcopy__(self, memo: dict) -> StreamedController:
        """A copy that streams the plans it holds and cannot plan (a solver's state cannot
        be copied): what a loop's warm-up needs, one stepped period."""
        twin = copy.copy(self)
        twin.streamer = self.streamer.copy()
        twin.planner = None  # type: ignore[assignment]
        twin._thread, twin._wall_clock, twin._t0 = None, False, None
        twin.streamer_times_s, twin.ages_s, twin.lateness_s = [], [], []
        twin.qd_prev = self.qd_prev.copy()
        return twin

    @property
    def lead_k(self) -> int:
        """Samples from a plan's measurement to its start."""
        return self.plan_periods if self._wall_clock else self.lead_periods

    def _reset_memory(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        self.close()
        self.planner_controller.reset(q0, qd0, self.sigma)
        self.trajectory = self.planner_controller.trajectory
        self.streamer.restart(q0, self.sigma)
        self._clear_requests()
        self.planner.step_times_s.clear()
        self.streamer_times_s.clear()
        self.ages_s.clear()
        self.lateness_s.clear()
        self._next_id = 1
        self._start_state = (q0.copy(), qd0.copy())
        self.qd_before_prev = qd0.copy()
        request = project(self.streamer, q0, qd0, 0, self._take_id())
        self.streamer.offer(self.planner.plan(request))  # the first plan, before the clock
        self.first_plan_s = self.planner.step_times_s.pop()  # its iterations from rest
        self.streamer.copy().step()  # loads the compiled period before the clock, too
        self._t0 = None

    def _take_id(self) -> int:
        self._next_id += 1
        return self._next_id - 1

    # ------------------------------------------------------------------ one period
    def _step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        start = time.perf_counter()
        self.qd_before_prev = self.qd_prev
        streamer, k = self.streamer, self.streamer.k
        streamer.take_due()
        if self._wall_clock and self._t0 is None:
            self._t0 = start
        if self._thread is not None:
            self._take_plan()
        if (k % self.plan_periods == 0 and k > 0) or self._stop_unasked:
            self._ask_plan(q, qd)
        sample = streamer.step()
        now = time.perf_counter()
        spent, late = now - start, float("nan")
        if self._t0 is not None:  # the command's time after the sample's place on the grid
            late = now - (self._t0 + k * self.period_s)
            self.lateness_s.append(late)
            if late > self.period_s:  # the whole periods past are skipped, as the loop does
                self._t0 += (late // self.period_s) * self.period_s
        self.streamer_times_s.append(spent)
        self.ages_s.append(sample.plan_age_s)
        return self._result(q, sample, spent, late)

    def _take_plan(self) -> None:
        """Offer the plan the planner finished since the last call, if any."""
        assert self._thread is not None
        plan = self._thread.take()
        if plan is not None:
            self.streamer.offer(plan)

    def _ask_plan(self, q: np.ndarray, qd: np.ndarray | None) -> None:
        """Ask for a plan from the measurement ``q``, ``qd`` starting ``lead_k`` samples on
        (on the wall clock: handed to the planner, unless it is still busy; stepped: solved
        and offered now)."""
        streamer, fresh, stop = self.streamer, self._fresh, self._stop_plans
        qd_meas = np.zeros(self.n) if qd is None else qd
        if self._thread is not None:
            args = (streamer.copy(), q, qd_meas, self.lead_k, self._next_id, fresh, stop)
            if self._thread.request(*args):
                self._next_id += 1
                self._fresh = self._stop_unasked = False
            return
        request = project(streamer, q, qd_meas, self.lead_k, self._take_id(), self.planner.lag_s)
        self._fresh = self._stop_unasked = False
        streamer.offer(self.planner.plan(request, fresh, stop))

    #: A stop is the planner's (its stop's plans, streamed): the stream plays its present
    #: plan, or holds the last command, until the first of them starts.
    stops_itself = True

    def _begin_stop(self) -> None:
        """Ask for the planner's stop at the next sample, not a plan period later; at the
        task's end nothing changes: the plans there already end at rest at the path's
        end, and the stream keeps following them (a stop plan would hold the arm where
        the stream's tracking of the last plans left it)."""
        if super().done:
            return
        self._stop_plans = self._stop_unasked = True

    # ------------------------------------------------------------------ taking over
    def take_over(
        self,
        q: np.ndarray,
        qd: np.ndarray | None,
        sigma: float,
        u: np.ndarray,
        a: np.ndarray,
        s: float,
        stop: bool = False,
    ) -> None:
        """Continue another controller's run on the same task from this sample: measured
        ``q`` [rad], ``qd`` [rad/s], its phase ``sigma`` [s], last command ``u`` [rad/s],
        that command's acceleration ``a`` [rad/s²] and its time scaling ``s``. The stream
        restarts there and asks for a plan starting ``lead_k`` samples on (the other
        controller's command and phase rate held in the projection); until a plan starts
        (:attr:`awaits_plan`) the other controller keeps commanding and reports each
        command (:meth:`follow`), and the plan's switch blends from the last
        (docs/theory.md §8.10). With ``stop`` the plans are the planner's stop."""
        self.sigma, self.qd_prev = float(sigma), np.array(u, dtype=float)
        self.qd_before_prev = self.qd_prev - self.period_s * np.asarray(a, dtype=float)
        self._clear_requests()
        self.stopping = self._stop_plans = bool(stop)
        self.streamer.take_over(q, sigma, u, a, s)
        self._t0 = time.perf_counter() if self._wall_clock else None
        if self._thread is not None:
            self._take_plan()  # a plan left from before (none: the planner was idle)
            self.streamer.pending = None
        self._fresh = True  # the planner's memory is of its own start, not of this state
        self._ask_plan(q, qd)

    @property
    def awaits_plan(self) -> bool:
        """Whether, after :meth:`take_over`, no plan has started yet (nor starts at this
        sample): the other controller still commands."""
        streamer = self.streamer
        if streamer.plan is not None:
            return False
        if self._thread is not None:
            self._take_plan()
        pending = streamer.pending
        return pending is None or pending.start_k > streamer.k

    def follow(self, q: np.ndarray, qd: np.ndarray | None, u: np.ndarray, sigma: float) -> None:
        """This sample's command ``u`` [rad/s] and the phase after it ``sigma`` [s] came from
        the controller taken over (:attr:`awaits_plan`); measured ``q``, ``qd``. A new plan
        is asked for every plan period (a late one was refused), and at once for a stop
        requested meanwhile."""
        k = self.streamer.k
        if (k % self.plan_periods == 0 and k > 0) or self._stop_unasked:
            self._ask_plan(q, qd)
        self.streamer.follow(np.asarray(u, dtype=float), sigma)
        self.qd_before_prev = self.qd_prev
        self.qd_prev, self.sigma = self.streamer.tracker.u.copy(), float(sigma)

    def _result(self, q: np.ndarray, sample: StreamSample, spent: float, late: float) -> StepResult:
        target = self.trajectory.target(sample.sigma)
        pose = self.robot.fast.poses(q[None, :])[0]
        if float(pose.dot(target)) < 0.0:
            pose = -pose
        diag = StreamDiagnostics(
            status=sample.mode, step_time_s=spent, message=self.streamer.playout_note,
            plan_id=sample.plan_id, plan_age_s=sample.plan_age_s, lateness_s=late,
        )  # fmt: skip
        s = (sample.sigma_next - sample.sigma) / self.period_s
        return StepResult(sample.u, s, sample.sigma, sample.sigma_next, pose, target, diag)

    #: The stream's end is its plans' (the planner's own end, at rest by default): it is
    #: never handed over (:meth:`finish_at_rest` does nothing, and the loop does not ask).
    ends_at_rest = True

    @property
    def done(self) -> bool:
        """The task's end with the stream settled there (:meth:`_settled`), or the
        play-out finished at rest."""
        if self._last_mode == "stopped":
            return True
        return super().done and self._settled()

    def _settled(self) -> bool:
        """Whether, at the task's end, the stream has settled on the path's end: its
        command and its plan's first one below :data:`SETTLED_RAD_S` (the plans there only
        correct the tool's position: the stream's tracking of the braking plans leaves
        the tool up to 0.1 mm past the end), or :data:`SETTLE_PLANS` plan periods on."""
        streamer = self.streamer
        if self._end_k is None:
            self._end_k = streamer.k
        if streamer.k - self._end_k >= SETTLE_PLANS * self.plan_periods:
            return True
        plan = streamer.plan
        first = 0.0 if plan is None else float(np.max(np.abs(plan.qd[0])))
        return max(first, float(np.max(np.abs(streamer.tracker.u)))) < SETTLED_RAD_S

    @property
    def _last_mode(self) -> str:
        s = self.streamer
        return (
            "stopped"
            if s.playing_out and s.rate == 0.0 and not np.any(np.abs(s.tracker.u) >= 1e-9)
            else ""
        )

    def report(self) -> dict:
        """The stream's figures for the log's ``meta["stream"]``."""
        steps = np.asarray(self.planner.step_times_s or [0.0])
        stream = np.asarray(self.streamer_times_s or [0.0])
        ages = np.asarray(self.ages_s or [0.0])
        out = {
            "period_s": self.period_s,
            "plan_period_s": self.plan_period_s,
            "wall_clock": self._wall_clock,
            "plans": len(self.planner.step_times_s) + 1,
            "first_plan_ms": 1e3 * self.first_plan_s,
            "planner_warm_up_ms": [1e3 * t for t in self.warm_up_s],
            "plans_used": self.streamer.switches,
            "plans_refused": self.streamer.refused,
            "planner_step_median_ms": 1e3 * float(np.median(steps)),
            "planner_step_max_ms": 1e3 * float(np.max(steps)),
            "streamer_step_median_us": 1e6 * float(np.median(stream)),
            "plan_age_median_ms": 1e3 * float(np.median(ages)),
            "plan_age_max_ms": 1e3 * float(np.max(ages)),
            "playout": self.streamer.playout_note,
        }
        if self.lateness_s:
            late = 1e3 * np.asarray(self.lateness_s)
            out["lateness_median_ms"] = float(np.median(late))
            out["lateness_p99_ms"] = float(np.percentile(late, 99))
            out["lateness_max_ms"] = float(np.max(late))
            out["late_commands"] = int(np.sum(late > 1e3 * self.period_s))
        out.update(self._thread_stats)
        return out


def _default_acceleration(planner: PathFollowingController) -> np.ndarray:
    """The stream's acceleration bound where none is given [rad/s²]: the robot's
    ``qdd_max`` where finite, else twice the planner's own bound (its constant, or the cap
    of its dynamics-aware one), so that the plan's velocity steps fit their blends
    (docs/theory.md §12.2)."""
    robot = np.asarray(planner.robot.limits.qdd_max, dtype=float)
    own = planner.a_const if planner.a_const is not None else planner.acceleration_cap
    return np.where(np.isfinite(robot), robot, 2.0 * np.broadcast_to(own, robot.shape))


def _limit(name: str, value, default: np.ndarray, n: int) -> np.ndarray:
    if value is None:
        return np.array(default, dtype=float)
    if np.all(np.isinf(np.asarray(value, dtype=float)) & (np.asarray(value, dtype=float) > 0)):
        return np.full(n, np.inf)
    return per_joint(name, value, n, name.split("_")[0] + " limit")


def streamed(
    planner: PathFollowingController,
    period_s: float,
    **options,
) -> StreamedController:
    """``planner`` (a path-following controller whose ``period_s`` is the plan period
    ``T_p``) streamed at ``period_s = T`` (``T_p`` a whole multiple of ``T``).

    Options: ``acceleration_max``, ``jerk_max`` (per joint or scalar [rad/s²], [rad/s³];
    default the robot's ``qdd_max`` — where it gives none, twice the planner's own bound —
    and ``qddd_max``, infinite when not given; the stream follows the plan closest when
    the planner's acceleration bound is at most half ``acceleration_max``),
    ``lead_periods`` (stepped mode: 0, or ``T_p/T`` to start each plan one plan period
    after its measurement as on the wall clock), ``planner_in`` (on the wall clock:
    ``"process"``, the default, or ``"thread"``), ``patience_plans`` (plan periods without a
    new plan before the play-out), ``feedback_s`` (the pull onto the plan's positions).

    Raises:
        ParameterError: ``planner`` is not a path-following controller (the thesis's
            controllers have no consistent plan), or ``T_p`` is not a whole multiple ≥ 1
            of ``T``.
    """
    return StreamedController(planner, period_s, **options)
