"""The closed loop: a controller against a joint driver, sampled every period ``T``.

Per sample k: read the measurement ``(t_k, q_k, qd_k)`` (the driver's joint order mapped to
the model's by name), run one controller step, write its velocity command (held for one
period), read the next measurement, and record sample k with the torques of the period
that followed. The log (:class:`~dqcontrol.runs.log.RunLog`) and the metrics are the same
for every driver.

Before the first command the loop checks the driver's joints against the model's
(:func:`~dqcontrol.sim.driver.joint_map`) and runs one step of a copy of the controller, so
that the compiled kernels are loaded before the clock starts.

A watchdog ends the run on a stale measurement (no newer sample for ``stale_periods``
periods), a missed deadline (wall-clock mode), the end of the task or the time limit, or
Ctrl-C; with ``brake=True`` it then brings the command to zero within the controller's
acceleration limit (``|Δu| ≤ a_max T`` per period) and holds. Braking happens after the
last logged sample: the log and the metrics are those of the task.
"""

from __future__ import annotations

import copy
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dqcontrol.controllers.base import Controller, StepResult, check_positive
from dqcontrol.errors import DQControlError, ParameterError
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.log import LogRecorder, RunLog
from dqcontrol.runs.metrics import Metrics, compute_metrics
from dqcontrol.sim.driver import JointDriver, joint_map
from dqcontrol.sim.mujoco_sim import Measurement

__all__ = ["RunResult", "run_loop"]

#: Longest brake [periods]; a command that cannot reach zero by then is set to zero.
MAX_BRAKE_PERIODS = 10_000


@dataclass(frozen=True)
class RunResult:
    """A finished (or interrupted) run: its log and metrics, and whether it was cut short."""

    log: RunLog
    metrics: Metrics
    interrupted: bool = False
    note: str = ""
    #: why the run was cut short: ``""`` (it was not), ``"user"`` (Ctrl-C),
    #: ``"simulation"`` (the driver or simulator failed; the note says how), ``"stale"``
    #: (no fresh measurement) or ``"deadline"`` (a step missed its period in wall-clock mode).
    reason: str = ""


def _warm_up(controller: Controller, q: np.ndarray, qd: np.ndarray) -> str:
    """One step of a deep copy of ``controller`` (loads the compiled kernels; the controller
    itself is untouched). Returns ``""`` or why it was skipped."""
    memo = {id(m): m for m in list(sys.modules.values())}  # modules are shared, not copied
    try:
        twin = copy.deepcopy(controller, memo)
        twin.step(q.copy(), qd.copy())
    except Exception as exc:  # noqa: BLE001 - a warm-up never stops the run
        return f"skipped: {type(exc).__name__}: {exc}"
    return ""


def _brake_rate(controller: Controller, q: np.ndarray) -> np.ndarray:
    """Largest change of the command per period [rad/s] (inf: stop in one period)."""
    spec = bounds_of(controller, q[None, :])
    a = spec.a_max
    if a is None and spec.a_max_per_sample is not None:
        a = spec.a_max_per_sample[0]
    if a is None:
        return np.full(q.shape, np.inf)
    return np.broadcast_to(np.asarray(a, dtype=float) * controller.period_s, q.shape)


class _Clock:
    """Pacing of the wall-clock mode (none in stepped mode)."""

    def __init__(self, period_s: float, realtime: bool) -> None:
        self.period_s, self.realtime = period_s, realtime
        self.start = time.perf_counter()
        self.k = 0
        self.lateness_s: list[float] = []

    def restart(self) -> None:
        self.start, self.k = time.perf_counter(), 0

    def wait(self) -> bool:
        """End of a period: sleep until its deadline; ``False`` if it was already missed."""
        self.k += 1
        if not self.realtime:
            return True
        deadline = self.start + self.k * self.period_s
        late = time.perf_counter() - deadline
        self.lateness_s.append(late)
        if late > 0.0:
            return False
        time.sleep(-late)
        return True


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
) -> RunResult:
    """Run ``controller`` against ``driver`` until ``σ ≥ T_tot``, ``max_time_s`` or the watchdog.

    Args:
        controller: any controller; its ``robot.joint_names`` are the model's joints.
        driver: a :class:`~dqcontrol.sim.driver.JointDriver`; its joints are mapped to the
            model's by name.
        q0: start configuration [rad] in the *model's* joint order; the driver must then be
            simulated (have ``reset``). ``None``: start where the driver's first
            measurement is.
        max_time_s: stop after this time [s] of the loop (default ``10 T_tot + 1 s``).
        meta: added to the log's ``meta`` (after ``simulator``, ``controller``,
            ``period_s``, the driver's own entries and ``joint_names``).
        on_sample: ``f(k, driver, result)`` after each sample.
        on_progress: ``f(σ_next, T_tot)`` [s] after each sample (e.g. a progress bar).
        realtime: pace the loop on the wall clock (one sample per ``T``); a step that
            ends after its period's deadline stops the run (``reason = "deadline"``).
            Otherwise the loop runs as fast as the driver answers (simulated time).
        stale_periods: the run stops (``reason = "stale"``) when the measurement has not
            been renewed for this many periods.
        brake: after the run, ramp the command to zero within the acceleration limit and
            hold (not logged; ``meta["stop"]`` says how many periods it took).
        warm_up: step a copy of the controller once before the first command.

    Returns:
        :class:`RunResult`; Ctrl-C, a driver or simulator error, a stale measurement or a
        missed deadline keep the completed samples (``interrupted=True``, a ``note``). The
        log's ``meta["stop"]`` says why the run ended and how long it braked, and
        ``meta["driver_report"]`` holds the driver's ``report()`` where it has one.

    Raises:
        JointMismatchError: the driver's joints are not the model's (before any command).
        ParameterError: a bad ``max_time_s``/``stale_periods``, or ``q0`` with a driver that
            cannot be reset.
    """
    robot = controller.robot
    period = controller.period_s
    names = tuple(robot.joint_names)
    perm = joint_map(driver.joint_names, names)
    inv = None if perm is None else np.argsort(perm)
    if isinstance(stale_periods, bool) or not isinstance(stale_periods, int | np.integer):
        raise ParameterError(f"stale_periods must be an integer ≥ 1, got {stale_periods!r}")
    if stale_periods < 1:
        raise ParameterError(f"stale_periods must be an integer ≥ 1, got {stale_periods!r}")
    duration = controller.trajectory.duration
    limit = (
        10.0 * duration + 1.0
        if max_time_s is None
        else check_positive("max_time_s", max_time_s, "s")
    )

    def to_model(m: Measurement) -> tuple[np.ndarray, np.ndarray]:
        if perm is None:
            return m.q, m.qd
        return np.asarray(m.q)[perm], np.asarray(m.qd)[perm]

    def to_driver(u: np.ndarray) -> np.ndarray:
        return u if inv is None else u[inv]

    if q0 is not None:
        q0 = robot.check_q(q0, "q0")
        if not hasattr(driver, "reset"):
            raise ParameterError(
                f"q0 is given but {type(driver).__name__} cannot be reset (a real arm starts "
                "where it is: pass q0=None)"
            )
        meas = driver.reset(to_driver(q0))
    else:
        meas = driver.read()
    q, qd = to_model(meas)
    controller.reset(q)
    info = dict(getattr(driver, "meta", {}))
    info = {
        "simulator": info.pop("simulator", type(driver).__name__),
        "controller": controller.name,
        "period_s": period,
        **info,
        "joint_names": list(names),
    }
    if warm_up:
        why = _warm_up(controller, np.asarray(q, dtype=float), np.zeros(robot.nq))
        if why:
            info["warm_up"] = why
    info.update(meta or {})
    rec = LogRecorder(robot.nq, info)
    interrupted, note, reason = False, "", ""
    num = int(np.ceil(limit / period - 1e-9))
    clock = _Clock(period, bool(realtime))
    command = np.zeros(robot.nq)
    newest, unchanged = meas.t_s, 0
    try:
        for k in range(num):
            if unchanged >= stale_periods:
                interrupted, reason = True, "stale"
                note = (
                    f"stopped after {len(rec)} samples: the measurement (t = {newest:.4f} s) "
                    f"was not renewed for {unchanged} periods"
                )
                break
            result = controller.step(q, qd)
            command = result.qd_command
            driver.write(to_driver(command))
            nxt = driver.read()
            rec.record(meas.t_s, q, qd, result, nxt.torque, nxt.torque_peak)
            if on_sample is not None:
                on_sample(k, driver, result)
            if on_progress is not None:
                on_progress(float(result.sigma_next), duration)
            if controller.done:
                break
            if nxt.t_s > newest:
                newest, unchanged = nxt.t_s, 0
            else:
                unchanged += 1
            meas = nxt
            q, qd = to_model(meas)
            if not clock.wait():
                interrupted, reason = True, "deadline"
                note = (
                    f"stopped after {len(rec)} samples: sample {k} ended "
                    f"{1e3 * clock.lateness_s[-1]:.2f} ms after its deadline"
                )
                break
    except KeyboardInterrupt:
        interrupted, reason = True, "user"
        note = f"interrupted by the user after {len(rec)} samples"
    except DQControlError as exc:
        interrupted, reason = True, "simulation"
        note = f"simulation stopped after {len(rec)} samples: {exc}"
    stop: dict = {"reason": reason or "end", "brake_periods": 0}
    if realtime and clock.lateness_s:
        late = np.asarray(clock.lateness_s)
        stop["lateness_max_ms"] = float(1e3 * late.max())
        stop["lateness_median_ms"] = float(1e3 * np.median(late))
    if brake and reason != "simulation":
        stop["brake_periods"] = _brake_and_hold(
            driver, np.array(command, dtype=float), _brake_rate(controller, q), to_driver, clock
        )
    log = rec.finish()
    log.meta["stop"] = stop
    report = getattr(driver, "report", None)
    if callable(report):  # the driver's own counters (e.g. the bridge's rejected packets)
        log.meta["driver_report"] = report()
    if note:
        log.meta["note"] = note
    metrics = compute_metrics(log, controller.trajectory, bounds_of(controller, log.q), period)
    return RunResult(log, metrics, interrupted, note, reason)


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
