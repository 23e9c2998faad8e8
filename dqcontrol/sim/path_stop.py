"""The closed loop's stop along the path (docs/theory.md §8.10, docs/user_guide.md).

When a run ends — the task done, Ctrl-C, a stale measurement, a missed deadline, a driver
error — the loop asks the controller to stop (:meth:`~dqcontrol.controllers.base.
Controller.request_stop`) and keeps stepping it, one sample a period, until its phase and
command are at rest: the arm brakes along the path, within every limit the controller has.
The samples are logged with the ``stopping`` flag. When the measurement is no longer renewed,
the controller is given the state the last commands lead to (dead reckoning). The last
command, once within :data:`REST_SHARE` of one period's acceleration of zero, is sent as
exactly zero.

Where the controller has no solution (its fallback) or the stop does not reach rest within
:data:`MAX_STOP_S`, the stop gives up: the loop's joint-space ramp takes over, and
``meta["stop"]["ramp"]`` says why.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.controllers.base import StepResult
from dqcontrol.errors import DQControlError
from dqcontrol.runs.mcap_log import RunLogWriteError

__all__ = ["PathStop", "stop_along_path"]

#: The command counts as at rest once every joint's is within this share of one period's
#: acceleration bound (``a_max T``) of zero, the phase velocity below :data:`REST_SCALING`
#: (the phase is the controller's own: behind a servo's lag the path level may keep a
#: trace of ``s`` while the joints are at rest).
REST_SHARE = 0.1
REST_SCALING = 1e-2
#: Longest stop [s] before the joint-space ramp takes over.
MAX_STOP_S = 5.0


if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.sim.loop import _Samples as _Run


@dataclasses.dataclass
class PathStop:
    """How a stop along the path went: its periods, whether it reached rest, and else why
    the ramp takes over (``ramp``)."""

    periods: int = 0
    at_rest: bool = False
    ramp: str = ""


def _at_rest(result: StepResult, sent: np.ndarray, rate: np.ndarray) -> bool:
    """Whether the command may now be zero: the phase at rest, the step's command within
    :data:`REST_SHARE` of ``rate`` and the last one sent (``sent``) within ``rate`` of
    zero."""
    return (
        result.s <= REST_SCALING
        and bool(np.all(np.abs(result.qd_command) <= REST_SHARE * rate))
        and bool(np.all(np.abs(sent) <= rate))
    )


def stop_along_path(run: _Run, rate: np.ndarray, record: bool = True) -> PathStop:
    """Step ``run.controller`` with its stop requested until it is at rest (``rate``: the
    largest change of the command per period [rad/s], per joint); the samples recorded
    (``record``) with the ``stopping`` flag. A second Ctrl-C or a driver error ends it
    (``ramp`` says which)."""
    controller, period = run.controller, run.controller.period_s
    out = PathStop()
    try:
        controller.request_stop()
        _latest_state(run)
        run.clock.restart()  # the stop's own periods, from now
        limit = int(np.ceil(MAX_STOP_S / period))
        while out.periods < limit:
            result = controller.step(run.q, run.qd)
            if result.diagnostics.fallback:
                out.ramp = f"no QP solution at stop sample {out.periods}: joint-space ramp"
                return out
            out.at_rest = _at_rest(result, run.command, rate)
            if out.at_rest:
                result = dataclasses.replace(result, qd_command=np.zeros_like(result.qd_command))
            _send_and_read(run, result, period, record)
            out.periods += 1
            if out.at_rest:
                return out
        out.ramp = f"not at rest after {MAX_STOP_S:g} s of stop: joint-space ramp"
    except KeyboardInterrupt:
        out.ramp = "interrupted again during the stop: joint-space ramp"
    except DQControlError as exc:
        out.ramp = f"driver error during the stop ({exc}): joint-space ramp"
    return out


def _latest_state(run: _Run) -> None:
    """The state the stop starts from: a measurement newer than the last one used (the run
    may have been cut between a command and its measurement), else the loop's (moved by
    the commands sent since the last fresh one)."""
    nxt = run.driver.read()
    if nxt.t_s > run.meas.t_s:
        run.meas = nxt
        run.q, run.qd = run.order.to_model(nxt)


def _send_and_read(run: _Run, result: StepResult, period: float, record: bool) -> None:
    """Write the command, read the next measurement (dead reckoning where it is not
    newer), record the sample (a log that cannot be written is left alone)."""
    run.command = result.qd_command
    run.driver.write(run.order.to_driver(run.command))
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
    run.clock.wait()
