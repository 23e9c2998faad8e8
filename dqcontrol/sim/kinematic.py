"""The kinematic closed loop: ideal velocity tracking, ``q_{k+1} = q_k + T qd_k``.

No physics: the command is integrated exactly over one period
(:class:`~dqcontrol.sim.driver.KinematicDriver` in :func:`~dqcontrol.sim.loop.run_loop`). It
runs any controller on any trajectory in milliseconds, for tests and quick experiments, and
produces the same :class:`~dqcontrol.runs.log.RunLog` and metrics as the MuJoCo loop.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np

from dqcontrol.controllers.base import Controller
from dqcontrol.sim.driver import KinematicDriver
from dqcontrol.sim.loop import RunResult, run_loop

__all__ = ["RunResult", "run_kinematic"]


def run_kinematic(
    controller: Controller,
    q0: np.ndarray,
    *,
    max_time_s: float | None = None,
    meta: dict | None = None,
    on_progress: Callable[[float, float], None] | None = None,
    brake: bool = False,
    log_file: str | os.PathLike | None = None,
) -> RunResult:
    """Run ``controller`` from ``q0`` [rad] until ``σ ≥ T_tot`` or ``max_time_s`` [s].

    ``max_time_s`` defaults to ``10 T_tot + 1 s`` (an infeasible task may scale to ``s → 0``
    and never finish; the run then stops and reports ``completed = False``).
    ``on_progress(σ_next, T_tot)`` is called after each sample; ``brake``: as
    :func:`~dqcontrol.sim.loop.run_loop` (off: the arm is left in the state the last
    command led to); ``log_file``: stream the log to this ``.mcap`` (as
    :func:`~dqcontrol.sim.loop.run_loop`).
    """
    driver = KinematicDriver(controller.robot, controller.period_s)
    return run_loop(
        controller,
        driver,
        q0=q0,
        max_time_s=max_time_s,
        meta=meta,
        on_progress=on_progress,
        brake=brake,
        log_file=log_file,
    )
