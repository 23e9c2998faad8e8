"""The closed loop: a controller against a joint driver, sampled every period ``T``.

Per sample k: read the measurement ``(t_k, q_k, qd_k)`` (the driver's joint order mapped to
the model's by name), run one controller step, write its velocity command (held for one
period), wait for the period's end (wall-clock mode), read the next measurement, and
record sample k with the torques of the period that followed. A sample's work — from its
measurement to its command — is what must fit in the period; the arm's response to the
command arrives while the loop waits (a driver whose ``write`` only sends, as the
bridge's, overlaps its round trip with that wait). The log
(:class:`~dqcontrol.runs.log.RunLog`) and the metrics are the same for every driver.

Before the first command the loop checks the driver's joints against the model's
(:func:`~dqcontrol.sim.driver.joint_map`) and runs one step of a copy of the controller, so
that the compiled kernels are loaded before the clock starts.

In wall-clock mode each sample starts on the grid ``start + k T`` (a sleep, then a short
poll of the clock) and its deadline is the end of its period; a sample that misses it is
counted and the next one starts at once, in the grid's slot that holds the present (the
whole periods already past are skipped and counted: the arm keeps its last command over
them, as real controllers tolerate isolated lost packets); a sample ending more than
``max_lateness_s`` late stops the run. The garbage collector sees
only the run's own objects. The loop holds one BLAS thread for its whole length
(:func:`~dqcontrol.controllers.single_blas_thread`), so that no step switches the libraries
itself. A watchdog ends the run on a stale measurement (no newer sample for
``stale_periods`` periods), a sample later than ``max_lateness_s`` (wall-clock mode), the
end of the task or the
time limit, or Ctrl-C; a driver error ends it too. With ``brake=True`` every one of these
then brings the arm to rest along the path (:mod:`dqcontrol.sim.path_stop`): the
controller's stop is requested and it is stepped until at rest, those samples logged with
the ``stopping`` flag. Only where the controller has no solution does the loop fall back to
bringing each joint's command to zero within the acceleration limit (``|Δu| ≤ a_max T`` per
period), after the last logged sample, ``meta["stop"]["ramp"]`` saying why; then it holds.
"""

from __future__ import annotations

import array
import contextlib
import copy
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dqcontrol._blas import single_blas_thread
from dqcontrol._gc import young_gc_only
from dqcontrol.controllers.base import Controller, StepResult, check_positive
from dqcontrol.controllers.stop_delegate import END_HANDOVER_ERROR_M, EndLead
from dqcontrol.dq.algebra import translation
from dqcontrol.errors import DQControlError, ParameterError, user_interrupt
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.contacts import RunContacts
from dqcontrol.runs.log import LogRecorder, RunLog
from dqcontrol.runs.mcap_log import RunLogWriteError
from dqcontrol.runs.metrics import Metrics, compute_metrics
from dqcontrol.runs.stream import DEFAULT_CHUNK_S, StreamRecorder
from dqcontrol.runs.streamed_run import end_streamed
from dqcontrol.sim.driver import JointDriver, joint_map
from dqcontrol.sim.mujoco_sim import Measurement
from dqcontrol.sim.path_stop import stop_along_path
from dqcontrol.sim.priority import check_priority, realtime_priority
from dqcontrol.streaming.end import end_plan_period_s, end_stream
from dqcontrol.streaming.hook import stream_hook

__all__ = ["RunResult", "run_loop"]

#: Longest brake [periods]; a command that cannot reach zero by then is set to zero.
MAX_BRAKE_PERIODS = 10_000
#: Wall-clock mode: the last part of each wait [s] polls the clock instead of sleeping (a
#: sleep ends 0.1-0.3 ms after its target on a Linux host; a poll within a microsecond).
SPIN_S = 0.0005
#: The same with the loop in ``SCHED_FIFO`` [s]: its sleeps end within 0.05-0.1 ms, and
#: every microsecond it polls is one the other processes of a small machine do not get.
SPIN_RT_S = 0.00015


@dataclass(frozen=True)
class RunResult:
    """A finished (or interrupted) run: its log and metrics, and whether it was cut short."""

    log: RunLog
    metrics: Metrics
    interrupted: bool = False
    note: str = ""
    #: why the run was cut short: ``""`` (it was not), ``"user"`` (Ctrl-C),
    #: ``"simulation"`` (the driver or simulator failed; the note says how), ``"stale"``
    #: (no fresh measurement), ``"deadline"`` (a sample ended more than ``max_lateness_s``
    #: after its deadline in wall-clock mode),
    #: ``"request"`` (the controller's stop was requested, e.g. from ``on_sample``) or
    #: ``"log"`` (the streamed run log could not be written).
    reason: str = ""
    #: the streamed run log (``run_loop(log_file=...)``); ``log`` then holds only the
    #: samples of its last block(s), the file all of them (:func:`~dqcontrol.runs.load_run`).
    log_file: Path | None = None
    #: ``log`` holds every ``log_stride``-th sample of ``log_file`` (a long run loaded for
    #: display); 1: every sample (or no file).
    log_stride: int = 1
    #: the run's contacts and closest distance, when measured
    #: (:func:`~dqcontrol.sim.run_contacts.measure_contacts`); saved with the run.
    contacts: RunContacts | None = None


def _warm_up(
    controller: Controller, q: np.ndarray, qd: np.ndarray, timed: bool
) -> tuple[str, float]:
    """One step of a deep copy of ``controller``, then one of its stop, and for a task that
    ends at speed one of its end at rest (loads the compiled kernels; the controller itself
    is untouched). Returns ``""`` or why it was skipped, and where ``timed`` the time [s] of
    the end's first step once its kernels are loaded (NaN: the task ends at rest; inf: not
    measured)."""
    end_step_s = math.nan
    try:
        if not controller.ends_at_rest:
            end_step_s = math.inf
            _end_first_step_s(_copy(controller), q, qd)  # loads the end's kernels
            if timed:  # then timed, its kernels loaded
                end_step_s = _end_first_step_s(_copy(controller), q, qd)
        twin = _copy(controller)
        twin.step(q.copy(), qd.copy())
        twin.request_stop()  # and its stop (a delegate's first steps load their own kernels)
        twin.step(q.copy(), qd.copy())
    except Exception as exc:  # noqa: BLE001 - a warm-up never stops the run
        return f"skipped: {type(exc).__name__}: {exc}", end_step_s
    return "", end_step_s


def _copy(controller: Controller) -> Controller:
    """A deep copy of ``controller``, the modules shared (each copy its own memo: a memo
    kept from one copy would hand out that copy again)."""
    return copy.deepcopy(controller, {id(m): m for m in list(sys.modules.values())})


def _end_first_step_s(ender: Controller, q: np.ndarray, qd: np.ndarray) -> float:
    """The time [s] of the first step of ``ender``'s end at rest, handed over just before
    the end (where its rest rows are posed; ``ender`` not stepped yet: no solver workspace
    was copied)."""
    ender.reset(q.copy(), qd.copy(), max(0.0, ender.trajectory.duration - 2.0 * ender.period_s))
    ender.finish_at_rest(q.copy())
    start = time.perf_counter()
    ender.step(q.copy(), qd.copy())
    return time.perf_counter() - start


def _brake_rate(controller: Controller, q: np.ndarray) -> np.ndarray:
    """Largest change of the command per period [rad/s] (inf: stop in one period)."""
    spec = bounds_of(controller, q[None, :])
    a = spec.a_max
    if a is None and spec.a_max_per_sample is not None:
        a = spec.a_max_per_sample[0]
    if a is None:
        return np.full(q.shape, np.inf)
    return np.broadcast_to(np.asarray(a, dtype=float) * controller.period_s, q.shape)


#: A wall-clock run stops when a sample ends this many periods after its deadline (the arm
#: has then held one command for that long); shorter misses are counted.
MAX_LATE_PERIODS = 5

#: Samples of lateness and jitter the wall-clock mode keeps for its medians and p99 (the
#: most recent ones: 8 MB each at most, about 17 minutes at 1 kHz); the maxima and the
#: count of missed deadlines cover the whole run.
TIMING_WINDOW = 1 << 20
#: Late commands whose sample index ``meta["stop"]["late_command_samples"]`` lists (the
#: first ones; the count covers the whole run).
LATE_SAMPLES_LISTED = 1000


class _Window:
    """The last ``capacity`` values of a series (a ring of floats), with the whole
    series' maximum and its count of positive values: bounded memory for a run of any
    length."""

    def __init__(self, capacity: int = TIMING_WINDOW) -> None:
        self.values = array.array("d")
        self.capacity = capacity
        self.count = 0
        self.positive = 0
        self.maximum = -np.inf
        self.last = 0.0

    def append(self, value: float) -> None:
        if len(self.values) < self.capacity:
            self.values.append(value)
        else:
            self.values[self.count % self.capacity] = value
        self.count += 1
        self.positive += value > 0.0
        self.maximum = max(self.maximum, value)
        self.last = value

    def __len__(self) -> int:
        return self.count


class _Clock:
    """Pacing of the wall-clock mode (none in stepped mode): sample k starts at
    ``start + k T`` and must end by ``start + (k + 1) T``, its deadline.

    ``lateness_s``: end of each sample's work minus its deadline (> 0: missed);
    ``jitter_s``: start of each sample after the first minus its scheduled start (each a
    :class:`_Window`: the medians and p99 are over the last :data:`TIMING_WINDOW` samples,
    the maxima and the missed deadlines over the whole run).
    """

    def __init__(self, period_s: float, realtime: bool) -> None:
        self.period_s, self.realtime = period_s, realtime
        #: a sample later than this [s] stops the run (:func:`run_loop` sets it)
        self.max_lateness_s = np.inf
        #: the loop thread's real-time priority (``None``: the ordinary scheduler)
        self.priority: int | None = None
        #: grid slots skipped after missed deadlines (no command sent in them)
        self.skipped_periods = 0
        self.start = time.perf_counter()
        self.k = 0
        self.lateness_s = _Window()
        self.jitter_s = _Window()
        self.sent_s = _Window()
        self.late_samples: list[int] = []

    def restart(self) -> None:
        self.start, self.k = time.perf_counter(), 0

    def sent(self, sample: int) -> None:
        """Sample ``sample``'s command was written: its delay after the end of its slot
        (> 0: late; the first :data:`LATE_SAMPLES_LISTED` late samples are listed)."""
        if self.realtime:
            late = time.perf_counter() - self.start - (self.k + 1) * self.period_s
            self.sent_s.append(late)
            if late > 0.0 and len(self.late_samples) < LATE_SAMPLES_LISTED:
                self.late_samples.append(sample)

    def wait(self) -> bool:
        """End of a period: wait for its deadline. A missed one is counted and the next
        sample starts at once, in the grid's slot that holds the present (the whole
        periods already past are skipped: a loop whose work fills its period could never
        catch up with them); ``False`` if it was missed by more than ``max_lateness_s``."""
        self.k += 1
        if not self.realtime:
            return True
        deadline = self.start + self.k * self.period_s
        late = time.perf_counter() - deadline
        self.lateness_s.append(late)
        if late > 0.0:
            skipped = int(late // self.period_s)
            self.k += skipped
            self.skipped_periods += skipped
            return late <= self.max_lateness_s
        _sleep_until(deadline, SPIN_S if self.priority is None else SPIN_RT_S)
        self.jitter_s.append(time.perf_counter() - deadline)
        return True

    def report(self) -> dict:
        """``meta["stop"]``'s timing entries [ms]: lateness (max, median: negative is the
        slack left), start jitter (median, p99, max), the missed deadlines, the skipped
        periods and the late commands (written after their slot's end: their count, the
        largest delay and the first ones' sample indices)."""
        late, jitter, sent = self.lateness_s, self.jitter_s, self.sent_s
        if not (self.realtime and len(late)):
            return {}
        recent_jitter = 1e3 * np.asarray(jitter.values or [0.0])
        return {
            "lateness_max_ms": 1e3 * late.maximum,
            "lateness_median_ms": float(np.median(1e3 * np.asarray(late.values))),
            "jitter_median_ms": float(np.median(recent_jitter)),
            "jitter_p99_ms": float(np.percentile(recent_jitter, 99)),
            "jitter_max_ms": 1e3 * jitter.maximum if len(jitter) else 0.0,
            "missed_deadlines": late.positive,
            "skipped_periods": self.skipped_periods,
            "late_commands": sent.positive,
            "command_late_max_ms": 1e3 * sent.maximum if len(sent) else 0.0,
            "late_command_samples": list(self.late_samples),
        }


def _sleep_until(deadline: float, spin_s: float = SPIN_S) -> None:
    """Sleep until ``spin_s`` before ``deadline`` (``time.perf_counter`` seconds), then
    poll the clock until it passes."""
    left = deadline - time.perf_counter() - spin_s
    if left > 0.0:
        time.sleep(left)
    while time.perf_counter() < deadline:
        pass


def run_loop(
    controller: Controller,
    driver: JointDriver,
    *,
    q0: np.ndarray | None = None,
    max_time_s: float | None = None,
    meta: dict | None = None,
    on_sample: Callable[[int, JointDriver, StepResult], None] | None = None,
    on_progress: Callable[[float, float], None] | None = None,
    realtime: bool = False,
    stale_periods: int = 3,
    brake: bool = True,
    warm_up: bool = True,
    log_file: str | os.PathLike | None = None,
    log_chunk_s: float = DEFAULT_CHUNK_S,
    max_lateness_s: float | None = None,
    realtime_priority: int | None = None,
) -> RunResult:
    """Run ``controller`` against ``driver`` until ``σ ≥ T_tot``, ``max_time_s`` or the watchdog
    (the module docstring says how the samples, the wall clock and the stop go).

    Args:
        controller: any controller; its ``robot.joint_names`` are the model's joints.
        driver: a joint driver; its joints are mapped to the model's by name.
        q0: start [rad] in the model's order (needs ``driver.reset``); ``None``: as measured.
        max_time_s: stop after this time [s] of the loop (default ``10 T_tot + 1 s``).
        meta: added to the log's ``meta``.
        on_sample: ``f(k, driver, result)`` after each sample.
        on_progress: ``f(σ_next, T_tot)`` [s] after each sample.
        realtime: keep the wall clock (sample k at ``start + k T``); else as fast as it answers.
        stale_periods: stop (``"stale"``) after this many periods without a new measurement.
        brake: end at rest along the path, then hold; ``False``: end with the last command.
        warm_up: step a copy of the controller once before the first command.
        log_file: stream the log to this ``.mcap`` (the result keeps the last samples).
        log_chunk_s: longest stretch of samples [s] in one block of ``log_file``.
        max_lateness_s: a sample this late [s] stops the run; ``None``: five periods.
        realtime_priority: on the wall clock, the loop's ``SCHED_FIFO`` priority (1–99,
            :mod:`dqcontrol.sim.priority`); ``None``: the ordinary scheduler.

    Returns:
        :class:`RunResult`: an interrupted run keeps its samples and a note; ``meta["stop"]``
        says why it ended, with its stop and the timing [ms].

    Raises:
        JointMismatchError: the driver's joints are not the model's. RunLogWriteError: no
            ``log_file``. ParameterError: a bad option, or no privilege for the priority.
    """
    order = _JointOrder(driver.joint_names, tuple(controller.robot.joint_names))
    num = _sample_count(controller, max_time_s, stale_periods)
    lateness = _max_lateness(controller.period_s, max_lateness_s)
    check_priority(realtime_priority)
    # One BLAS thread from the reset on: the library's pool, woken each time a step gave its
    # threads back, spins for a while after, and would take the loop's core from it.
    with single_blas_thread():
        logging = (log_file, log_chunk_s)
        run = _started(controller, driver, order, q0, realtime, warm_up, meta, logging)
        run.clock.max_lateness_s = lateness
        run.clock.priority = realtime_priority if realtime else None
        stop = _with_stream(run, realtime, num, stale_periods, on_sample, on_progress, brake)
    return _result(controller, driver, run.rec, stop, run)


def _with_stream(run: _Samples, realtime, num, stale_periods, on_sample, on_progress, brake):
    """:func:`_samples_then_brake` with a streamed controller's planner running beside it
    (stopped after; its figures added to the log's ``meta``)."""
    stream = stream_hook(run.controller, realtime)
    try:
        stop = _samples_then_brake(run, num, stale_periods, on_sample, on_progress, brake)
    finally:
        stream.close()
        _close_end_stream(run)
    run.rec.meta.update(stream.meta())
    return stop


def _samples_then_brake(run: _Samples, num, stale_periods, on_sample, on_progress, brake) -> dict:
    """The run's samples on its clock, then the brake; ``meta["stop"]``. An exception that
    leaves it closes a streamed log without its end record (it then reads as cut short;
    the log's own write errors give way to that exception)."""
    if brake and not run.controller.ends_at_rest:
        _watch_the_end(run)
    try:
        with realtime_priority(run.clock.priority):
            with young_gc_only(run.clock.realtime), single_blas_thread():
                run.clock.restart()
                run.loop(num, stale_periods, on_sample, on_progress)
            return _stop_and_brake(run, brake)
    except BaseException:
        if isinstance(run.rec, StreamRecorder):
            with contextlib.suppress(RunLogWriteError):
                run.rec.close(None)
        raise


def _started(
    controller, driver, order, q0, realtime: bool, warm_up: bool, meta, logging
) -> _Samples:
    """The run at its first measurement: the controller reset there (and warmed up on a
    copy where ``warm_up``), its log opened (streamed to ``logging[0]`` in blocks of
    ``logging[1]`` seconds, unless ``None``) and its clock set."""
    robot = controller.robot
    meas = _first_measurement(driver, robot, q0, order)
    q, _qd = order.to_model(meas)
    controller.reset(q)
    info, end_step_s = _run_info(driver, controller, order.names, q, warm_up, meta, bool(realtime))
    log_file, chunk_s = logging
    rec: LogRecorder | StreamRecorder
    if log_file is None:
        rec = LogRecorder(robot.nq, info)
    else:
        rec = StreamRecorder(log_file, robot.nq, controller.period_s, info, chunk_s=chunk_s)
    clock = _Clock(controller.period_s, bool(realtime))
    run = _Samples(controller, driver, order, rec, clock, meas)
    run.end_step_s = end_step_s
    return run


def _max_lateness(period_s: float, max_lateness_s: float | None) -> float:
    """The checked lateness [s] past which a wall-clock run stops."""
    if max_lateness_s is None:
        return MAX_LATE_PERIODS * period_s
    if isinstance(max_lateness_s, bool) or not (float(max_lateness_s) >= 0.0):
        raise ParameterError(
            f"max_lateness_s must be a lateness >= 0 [s] (or None), got {max_lateness_s!r}"
        )
    return float(max_lateness_s)


def _sample_count(controller: Controller, max_time_s: float | None, stale_periods) -> int:
    """The most samples of a run (``max_time_s``, default ``10 T_tot + 1 s``); checks
    ``stale_periods``."""
    if (
        isinstance(stale_periods, bool)
        or not isinstance(stale_periods, int | np.integer)
        or stale_periods < 1
    ):
        raise ParameterError(f"stale_periods must be an integer ≥ 1, got {stale_periods!r}")
    limit = (
        10.0 * controller.trajectory.duration + 1.0
        if max_time_s is None
        else check_positive("max_time_s", max_time_s, "s")
    )
    return int(np.ceil(limit / controller.period_s - 1e-9))


def _stop_and_brake(run: _Samples, brake: bool) -> dict:
    """``meta["stop"]``: why the run ended, the timing on the wall clock
    (:meth:`_Clock.report`), the periods of the stop along the path (logged) and those of
    the joint-space ramp (``brake_periods``, after the last logged sample) with why
    (``ramp``)."""
    clock = run.clock
    stop: dict = {"reason": run.reason or "end", "brake_periods": 0, **clock.report()}
    if run.finished_at is not None:  # the task's end at rest, handed over from here
        stop["end_at_rest_from"] = {"sample": run.finished_at[0], "sigma": run.finished_at[1]}
    if not brake:
        return stop
    rate = _brake_rate(run.controller, run.q)
    path = stop_along_path(run, rate, record=run.reason != "log")
    stop.update(stop_periods=path.periods, at_rest=path.at_rest, ramp=path.ramp)
    if not path.at_rest:
        stop["brake_periods"] = _brake_and_hold(
            run.driver, np.array(run.command, dtype=float),
            rate, run.order.to_driver, clock,
        )  # fmt: skip
    else:
        with contextlib.suppress(KeyboardInterrupt, DQControlError):
            run.driver.hold()
    return stop


class _JointOrder:
    """The driver's joint order against the model's (by name; ``perm`` is ``None`` when
    they are the same)."""

    def __init__(self, driver_names, model_names: tuple[str, ...]) -> None:
        self.names = model_names
        self.perm = joint_map(driver_names, model_names)
        self.inv = None if self.perm is None else np.argsort(self.perm)

    def to_model(self, m: Measurement) -> tuple[np.ndarray, np.ndarray]:
        if self.perm is None:
            return m.q, m.qd
        return np.asarray(m.q)[self.perm], np.asarray(m.qd)[self.perm]

    def to_driver(self, u: np.ndarray) -> np.ndarray:
        return u if self.inv is None else u[self.inv]


def _first_measurement(driver, robot, q0, order: _JointOrder) -> Measurement:
    """The driver reset to ``q0`` (model order), or its present measurement."""
    if q0 is None:
        return driver.read()
    q0 = robot.check_q(q0, "q0")
    if not hasattr(driver, "reset"):
        raise ParameterError(
            f"q0 is given but {type(driver).__name__} cannot be reset (a real arm starts "
            "where it is: pass q0=None)"
        )
    return driver.reset(order.to_driver(q0))


def _run_info(
    driver, controller: Controller, names, q, warm_up: bool, meta, realtime: bool
) -> tuple[dict, float]:
    """The log's ``meta``: simulator, controller, period, the driver's own entries, joint
    names, the warm-up's note (the controller stepped once, in a copy, where ``warm_up``),
    then the caller's ``meta``; and the end's first step [s] the warm-up timed on the wall
    clock (``realtime``; inf: none)."""
    info = dict(getattr(driver, "meta", {}))
    info = {
        "simulator": info.pop("simulator", type(driver).__name__),
        "controller": controller.name,
        "period_s": controller.period_s,
        **info,
        "joint_names": list(names),
    }
    end_step_s = math.inf
    if warm_up:
        q0, qd0 = np.asarray(q, dtype=float), np.zeros(controller.robot.nq)
        why, end_step_s = _warm_up(controller, q0, qd0, timed=realtime)
        if why:
            info["warm_up"] = why
    info.update(meta or {})
    return info, end_step_s


def _watch_the_end(run: _Samples) -> None:
    """Watch for the end's handover (:class:`_EndWatch`). In simulated time, and on the
    wall clock where the end's first step (measured by the warm-up) takes at most
    :data:`END_STEP_SHARE` of a period, the end is a path-following controller stepped in
    the loop; on the wall clock otherwise it is streamed (:func:`~dqcontrol.streaming.end.
    end_stream`, prepared here, before the clock), and ``meta`` says so; without that
    measurement the task ends at speed, and ``meta`` says why. A streamed end the caller
    set (``controller.end_stream``) is used as it is."""
    period, given = run.controller.period_s, run.controller.end_stream
    if given is not None:  # the caller's (e.g. stepped, to be deterministic)
        run.end_watch = _EndWatch(run.controller, wait_s=2.0 * given.plan_period_s)
        return
    if not run.clock.realtime or run.end_step_s <= END_STEP_SHARE * period:
        run.end_watch = _EndWatch(run.controller)
        return
    plan_period_s = end_plan_period_s(run.end_step_s, period)
    if math.isinf(plan_period_s):
        run.rec.meta["end_at_rest"] = (
            "not handed over on the wall clock: the end's first step was not measured "
            "(warm_up=False); the task ends at speed"
        )
        return
    try:
        run.controller.end_stream = end_stream(run.controller, run.q, plan_period_s)
    except Exception as exc:  # noqa: BLE001 - the task then ends at speed, and says why
        run.rec.meta["end_at_rest"] = (
            f"not handed over on the wall clock: its streamed end could not be prepared "
            f"({type(exc).__name__}: {exc}); the task ends at speed"
        )
        return
    run.end_watch = _EndWatch(run.controller, wait_s=2.0 * plan_period_s)
    run.rec.meta["end_at_rest"] = (
        f"streamed on the wall clock: the end's first step ({1e3 * run.end_step_s:.1f} ms) "
        f"does not fit {END_STEP_SHARE:g} of the {1e3 * period:g} ms period; planned every "
        f"{1e3 * plan_period_s:g} ms in a process of its own"
    )


def _close_end_stream(run: _Samples) -> None:
    """Stop a streamed end's planner (:func:`_watch_the_end`); its figures to ``meta``."""
    ender = run.controller.end_stream
    if ender is None:
        return
    run.controller.end_stream = None
    ender.close()
    run.rec.meta["end_stream"] = ender.report()


#: The share of a period the end's first step may take on the wall clock.
END_STEP_SHARE = 0.25


class _EndWatch:
    """Whether a task that ends at speed is :func:`~dqcontrol.controllers.stop_delegate.
    end_lead_s` from its end with the tool within :data:`~dqcontrol.controllers.
    stop_delegate.END_HANDOVER_ERROR_M` of its target, where it hands its end to the
    rest-to-rest controller (:meth:`~dqcontrol.controllers.base.Controller.finish_at_rest`);
    the acceleration bound at the measured state refreshed every :data:`REFRESH` samples.
    ``wait_s`` [s]: how long the handover may take before that controller commands (the
    phase the task moves meanwhile is added to the lead)."""

    REFRESH = 10

    def __init__(self, controller: Controller, wait_s: float = 0.0) -> None:
        self.controller = controller
        self.wait_s = wait_s
        self.jerk = np.asarray(controller.robot.limits.qddd_max, dtype=float)
        self.lead: EndLead | None = None
        self.count = 0

    def due(self, result: StepResult, q: np.ndarray) -> bool:
        controller = self.controller
        if self.lead is None or self.count % self.REFRESH == 0:
            a_max = _brake_rate(controller, q) / controller.period_s
            self.lead = EndLead(a_max, self.jerk, q.shape)
        self.count += 1
        remaining = controller.trajectory.duration - controller.sigma
        if remaining > self.lead(result.s, result.qd_command) + self.wait_s * result.s:
            return False
        error_m = float(np.linalg.norm(translation(result.pose) - translation(result.target)))
        return error_m <= END_HANDOVER_ERROR_M


class _Samples:
    """The samples of one run: step, write, read, record, until the task ends or the
    watchdog (stale measurement, missed deadline), Ctrl-C or a driver error stops it."""

    def __init__(self, controller, driver, order, rec, clock, meas: Measurement) -> None:
        self.controller, self.driver, self.order = controller, driver, order
        self.rec, self.clock, self.meas = rec, clock, meas
        self.q, self.qd = order.to_model(meas)
        self.command = np.zeros(controller.robot.nq)
        #: where the commands sent since the last fresh measurement took the arm [rad]
        self.drift_rad = np.zeros(controller.robot.nq)
        self.interrupted, self.note, self.reason = False, "", ""
        #: when a task that ends at speed hands its end to the rest-to-rest controller
        #: (``None``: it does not; set where the run ends with the brake)
        self.end_watch: _EndWatch | None = None
        #: ``(sample, σ)`` where the task's end at rest was handed over (``None``: not)
        self.finished_at: tuple[int, float] | None = None
        #: the end's first step [s] measured by the warm-up (inf: not measured)
        self.end_step_s = math.inf

    def loop(self, num: int, stale_periods: int, on_sample, on_progress) -> None:
        try:
            self._loop(num, stale_periods, on_sample, on_progress)
        except (KeyboardInterrupt, SystemError) as exc:  # SystemError: through compiled code
            if not user_interrupt(exc):
                raise
            self._stop("user", f"interrupted by the user after {len(self.rec)} samples")
        except RunLogWriteError as exc:
            self._stop("log", f"stopped after {len(self.rec)} samples: {exc}")
        except DQControlError as exc:
            self._stop("simulation", f"simulation stopped after {len(self.rec)} samples: {exc}")

    def _stop(self, reason: str, note: str) -> None:
        self.interrupted, self.reason, self.note = True, reason, note

    def _loop(self, num: int, stale_periods: int, on_sample, on_progress) -> None:
        controller, driver, rec, clock = self.controller, self.driver, self.rec, self.clock
        duration = controller.trajectory.duration
        newest, unchanged = self.meas.t_s, 0
        for k in range(num):
            if unchanged >= stale_periods:
                self._stop("stale", (
                    f"stopped after {len(rec)} samples: the measurement (t = {newest:.4f} s) "
                    f"was not renewed for {unchanged} periods"
                ))  # fmt: skip
                return
            result = controller.step(self.q, self.qd)
            self.command = result.qd_command
            driver.write(self.order.to_driver(self.command))
            clock.sent(k)
            on_time = clock.wait()  # the arm moves over the period; its state comes after
            nxt = driver.read()
            rec.record(self.meas.t_s, self.q, self.qd, result, nxt.torque, nxt.torque_peak)
            if on_sample is not None:
                on_sample(k, driver, result)
            if on_progress is not None:
                on_progress(float(result.sigma_next), duration)
            if nxt.t_s > newest:
                newest, unchanged = nxt.t_s, 0
                self.drift_rad[:] = 0.0
            else:
                unchanged += 1
                self.drift_rad += controller.period_s * self.command
            self.meas = nxt
            self.q, self.qd = self.order.to_model(nxt)
            if unchanged:  # not renewed: where the commands since took the arm
                self.q = self.q + self.drift_rad
            if self.end_watch is not None and self.end_watch.due(result, self.q):
                self.end_watch = None
                controller.finish_at_rest(self.q, self.qd)
                if controller.finishing:
                    self.finished_at = (len(rec), float(controller.sigma))
            if controller.done:
                return
            if controller.stopping:
                self._stop("request", (
                    f"stop requested after {len(rec)} samples (σ = {controller.sigma:.4f} s)"
                ))  # fmt: skip
                return
            if not on_time:
                self._stop("deadline", (
                    f"stopped after {len(rec)} samples: sample {k} ended "
                    f"{1e3 * clock.lateness_s.last:.2f} ms after its deadline (more than "
                    f"{1e3 * clock.max_lateness_s:.2f} ms)"
                ))  # fmt: skip
                return


def _result(controller, driver, rec, stop: dict, run: _Samples) -> RunResult:
    """The run's log (with ``stop``, the driver's report and the note) and its metrics."""
    rec.meta["stop"] = stop
    report = getattr(driver, "report", None)
    if callable(report):  # the driver's own counters (e.g. the bridge's rejected packets)
        rec.meta["driver_report"] = report()
    if run.note:
        rec.meta["note"] = run.note
    if isinstance(rec, StreamRecorder):
        return _streamed_result(controller, rec, run)
    log = rec.finish()
    metrics = compute_metrics(
        log, controller.trajectory, bounds_of(controller, log.q), controller.period_s
    )
    return RunResult(log, metrics, run.interrupted, run.note, run.reason)


def _streamed_result(controller, rec: StreamRecorder, run: _Samples) -> RunResult:
    """The result of a streamed run: metrics from its file, then its end record; a log
    that cannot be finished makes the run interrupted (``reason = "log"``)."""
    window, metrics, failure = end_streamed(
        rec, controller.trajectory, lambda q: bounds_of(controller, q), controller.period_s,
        (run.interrupted, run.note),
    )  # fmt: skip
    interrupted, note, reason = run.interrupted, run.note, run.reason
    if failure:
        interrupted, reason = True, reason or "log"
        note = note if failure in note else f"{note}; {failure}" if note else failure
    if metrics is None:
        metrics = compute_metrics(
            window, controller.trajectory, bounds_of(controller, window.q), controller.period_s
        )
    return RunResult(window, metrics, interrupted, note, reason, rec.path)


def _brake_and_hold(driver, command, rate, to_driver, clock: _Clock) -> int:
    """Ramp ``command`` [rad/s] to zero by at most ``rate`` per period, then hold; the number
    of ramp periods. A second Ctrl-C or a driver error skips to the hold."""
    periods = 0
    u = command
    try:
        clock.restart()
        while np.any(u != 0.0) and periods < MAX_BRAKE_PERIODS:
            u = u - np.clip(u, -rate, rate)
            if periods == MAX_BRAKE_PERIODS - 1:
                u = np.zeros_like(u)
            driver.write(to_driver(u))
            periods += 1
            clock.wait()
    except (KeyboardInterrupt, DQControlError):
        pass
    try:
        driver.hold()
    except (KeyboardInterrupt, DQControlError):
        pass
    return periods
