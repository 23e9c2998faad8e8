"""The kinematic closed loop: ideal velocity tracking, ``q_{k+1} = q_k + T qd_k``.

No physics: the command is integrated exactly over one period. It runs any controller on
any trajectory in milliseconds, for tests and quick experiments, and produces the same
:class:`~dqcontrol.runs.log.RunLog` and metrics as the MuJoCo loop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dqcontrol.controllers.base import Controller, check_positive
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.log import LogRecorder, RunLog
from dqcontrol.runs.metrics import Metrics, compute_metrics

__all__ = ["RunResult", "run_kinematic"]


@dataclass(frozen=True)
class RunResult:
    """A finished (or interrupted) run: its log and metrics, and whether it was cut short."""

    log: RunLog
    metrics: Metrics
    interrupted: bool = False
    note: str = ""
    #: why the run was cut short: ``""`` (it was not), ``"user"`` (Ctrl-C) or
    #: ``"simulation"`` (the simulator failed; the note says how).
    reason: str = ""


def run_kinematic(
    controller: Controller,
    q0: np.ndarray,
    *,
    max_time_s: float | None = None,
    meta: dict | None = None,
) -> RunResult:
    """Run ``controller`` from ``q0`` [rad] until ``σ ≥ T_tot`` or ``max_time_s`` [s].

    ``max_time_s`` defaults to ``10 T_tot + 1 s`` (an infeasible task may scale to ``s → 0``
    and never finish; the run then stops and reports ``completed = False``).
    """
    robot = controller.robot
    q = robot.check_q(q0, "q0").copy()
    controller.reset(q)
    period = controller.period_s
    duration = controller.trajectory.duration
    limit = (
        10.0 * duration + 1.0
        if max_time_s is None
        else check_positive("max_time_s", max_time_s, "s")
    )
    steps = int(np.ceil(limit / period - 1e-9))
    info = {"simulator": "kinematic", "controller": controller.name, "period_s": period}
    info.update(meta or {})
    rec = LogRecorder(robot.nq, info)
    qd_meas = np.zeros(robot.nq)
    interrupted, note, reason = False, "", ""
    try:
        for k in range(steps):
            result = controller.step(q, qd_meas)
            rec.record(k * period, q, qd_meas, result)
            qd_meas = result.qd_command
            q = q + period * result.qd_command
            if controller.done:
                break
    except KeyboardInterrupt:
        interrupted, reason = True, "user"
        note = f"interrupted by the user after {len(rec)} samples"
    log = rec.finish()
    metrics = compute_metrics(log, controller.trajectory, bounds_of(controller, log.q), period)
    if note:
        log.meta["note"] = note
    return RunResult(log, metrics, interrupted, note, reason)
