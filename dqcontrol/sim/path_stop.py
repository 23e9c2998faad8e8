"""The closed loop's stop along the path (docs/theory.md §8.10, docs/user_guide.md).

When a run ends — the task done, Ctrl-C, a stale measurement, a missed deadline, a driver
error — the loop asks the controller to stop (:meth:`~dqcontrol.controllers.base.
Controller.request_stop`) and keeps stepping it, one sample a period, until its phase and
command are at rest: the arm brakes along the path, within every limit the controller has.
The samples are logged with the ``stopping`` flag. When the measurement is no longer renewed,
the controller is given the state the last commands lead to (dead reckoning). The last
command, once within :data:`REST_SHARE` of one period's acceleration of zero, is sent as
exactly zero where that zero keeps the acceleration and jerk bounds (from the last two
commands sent); else the controller keeps stepping.

Where the controller has no solution (its fallback) or the stop does not reach rest within
:data:`MAX_STOP_S`, the stop gives up: the loop's joint-space ramp takes over, and
``meta["stop"]["ramp"]`` says why.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.controllers.base import StepResult
from dqcontrol.dq.algebra import translation
from dqcontrol.errors import DQControlError, user_interrupt
from dqcontrol.runs.mcap_log import RunLogWriteError
from dqcontrol.sim.jerk_brake import jerk_brake_command

__all__ = ["PathStop", "stop_along_path"]

#: The command counts as at rest once every joint's is within this share of one period's
#: acceleration bound (``a_max T``) of zero, the phase velocity below :data:`REST_SCALING`
#: (the phase is the controller's own: behind a servo's lag the path level may keep a
#: trace of ``s`` while the joints are at rest).
REST_SHARE = 0.1
REST_SCALING = 1e-2
#: Longest stop [s] before the joint-space ramp takes over.
MAX_STOP_S = 5.0
#: Under a jerk bound, once the phase is at rest and the tool within this distance [m] of
#: its target, the joints finish with the jerk-limited braking law
#: (:func:`~dqcontrol.sim.jerk_brake.jerk_brake_command`) from the last two commands
#: sent: the path level alone, whose horizon does not see the jerk bound, keeps the joints
#: swinging round the path's point.
FINISH_ERROR_M = 1e-4


if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.sim.loop import _Samples as _Run


@dataclasses.dataclass
class PathStop:
    """How a stop along the path went: its periods, whether it reached rest, and else why
    the ramp takes over (``ramp``)."""

    periods: int = 0
    at_rest: bool = False
    ramp: str = ""


def _zero_allowed(sent: np.ndarray, before: np.ndarray, rate: np.ndarray, jerk_step) -> bool:
    """Whether a command of exactly zero after ``sent`` and ``before`` keeps the bounds:
    its acceleration ``|sent| ≤ rate`` (``ā T``), its jerk ``|before - 2 sent|`` and that
    of the hold after it ``|sent|`` within ``jerk_step`` (``j̄ T²``)."""
    return (
        bool(np.all(np.abs(sent) <= rate))
        and bool(np.all(np.abs(before - 2.0 * sent) <= jerk_step))
        and bool(np.all(np.abs(sent) <= jerk_step))
    )


def _at_rest(
    result: StepResult, sent: np.ndarray, before: np.ndarray, rate: np.ndarray, jerk_step
) -> bool:
    """Whether the command may now be zero: the phase at rest, the step's command within
    :data:`REST_SHARE` of ``rate`` and the zero within the bounds (:func:`_zero_allowed`)."""
    return (
        result.s <= REST_SCALING
        and bool(np.all(np.abs(result.qd_command) <= REST_SHARE * rate))
        and _zero_allowed(sent, before, rate, jerk_step)
    )


def stop_along_path(run: _Run, rate: np.ndarray, record: bool = True) -> PathStop:
    """Step ``run.controller`` with its stop requested until it is at rest (``rate``: the
    largest change of the command per period [rad/s], per joint); the samples recorded
    (``record``) with the ``stopping`` flag. Under a jerk bound the joints finish with the
    braking law once the phase is at rest on the path (:data:`FINISH_ERROR_M`). A second Ctrl-C
    or a driver error ends it (``ramp`` says which)."""
    controller, period = run.controller, run.controller.period_s
    jerk_step = np.asarray(controller.robot.limits.qddd_max, dtype=float) * period * period
    finishes = bool(np.any(np.isfinite(jerk_step)))
    before = np.array(getattr(controller, "qd_before_prev", run.command), dtype=float)
    out, last = PathStop(), None
    try:
        controller.request_stop()
        _latest_state(run)
        run.clock.restart()  # the stop's own periods, from now
        limit = int(np.ceil(MAX_STOP_S / period))
        while out.periods < limit:
            if last is None:
                result = controller.step(run.q, run.qd)
                if result.diagnostics.fallback:
                    out.ramp = f"no QP solution at stop sample {out.periods}: joint-space ramp"
                    return out
                out.at_rest = _at_rest(result, run.command, before, rate, jerk_step)
                if finishes and result.s <= REST_SCALING and _on_path(result):
                    last = result
            if last is not None:
                result = _finish(last, controller, run, before, rate, jerk_step)
                out.at_rest = _zero_allowed(run.command, before, rate, jerk_step)
            if out.at_rest:
                result = dataclasses.replace(result, qd_command=np.zeros_like(result.qd_command))
            before = np.array(run.command, dtype=float)
            _send_and_read(run, result, period, record)
            out.periods += 1
            if out.at_rest:
                return out
        out.ramp = f"not at rest after {MAX_STOP_S:g} s of stop: joint-space ramp"
    except (KeyboardInterrupt, SystemError) as exc:  # SystemError: through compiled code
        if not user_interrupt(exc):
            raise
        out.ramp = "interrupted again during the stop: joint-space ramp"
    except DQControlError as exc:
        out.ramp = f"driver error during the stop ({exc}): joint-space ramp"
    return out


def _on_path(result: StepResult) -> bool:
    """Whether the tool is within :data:`FINISH_ERROR_M` of its target."""
    return float(np.linalg.norm(translation(result.pose) - translation(result.target))) <= (
        FINISH_ERROR_M
    )


def _finish(last: StepResult, controller, run: _Run, before, rate, jerk_step) -> StepResult:
    """The sample of the braking law from the last two commands (``run.command``,
    ``before``) within ``rate`` (``ā T``) and ``jerk_step`` (``j̄ T²``): the phase held
    where the controller left it (``last``), the pose at the measured ``run.q``."""
    period = controller.period_s
    command = jerk_brake_command(run.command, before, rate / period, jerk_step / period**2, period)
    pose = controller.robot.pose(run.q)
    if float(pose.dot(last.target)) < 0.0:
        pose = -pose
    return dataclasses.replace(last, qd_command=command, pose=pose, s=0.0, sigma=last.sigma_next)


def _latest_state(run: _Run) -> None:
    """The state the stop starts from: a measurement newer than the last one used (the run
    may have been cut between a command and its measurement), else the loop's (moved by
    the commands sent since the last fresh one)."""
    nxt = run.driver.read()
    if nxt.t_s > run.meas.t_s:
        run.meas = nxt
        run.q, run.qd = run.order.to_model(nxt)


def _send_and_read(run: _Run, result: StepResult, period: float, record: bool) -> None:
    """Write the command, wait for the period's end, read the next measurement (dead
    reckoning where it is not newer), record the sample (a log that cannot be written is
    left alone)."""
    run.command = result.qd_command
    run.driver.write(run.order.to_driver(run.command))
    run.clock.wait()
    nxt = run.driver.read()
    meas = run.meas
    if record:
        try:
            run.rec.record(
                meas.t_s, run.q, run.qd, result, nxt.torque, nxt.torque_peak, stopping=True
            )
        except RunLogWriteError:
            pass
    if nxt.t_s > meas.t_s:
        run.meas = nxt
        run.q, run.qd = run.order.to_model(nxt)
    else:  # no fresh measurement: where the commands take the arm
        run.q = run.q + period * run.command
        run.qd = run.command.copy()
        run.meas = dataclasses.replace(meas, t_s=meas.t_s + period)
