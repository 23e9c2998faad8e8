"""The MuJoCo closed loop: the controller sampled every ``T``, the command held in between.

Per sample k: measure ``(q, qd)`` from the simulation, run one controller step, hold its
command for one period (an integer number of physics steps), record the sample with the
torques applied during that period. The log and metrics are those of the kinematic loop.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.base import Controller, check_positive
from dqcontrol.errors import DQControlError
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.log import LogRecorder
from dqcontrol.runs.metrics import compute_metrics
from dqcontrol.sim.kinematic import RunResult
from dqcontrol.sim.mujoco_sim import MujocoSimulation

__all__ = ["run_mujoco"]


def run_mujoco(
    controller: Controller,
    q0: np.ndarray,
    *,
    simulation: MujocoSimulation | None = None,
    max_time_s: float | None = None,
    meta: dict | None = None,
    on_sample=None,
    **sim_options,
) -> RunResult:
    """Run ``controller`` in MuJoCo from ``q0`` until ``σ ≥ T_tot`` or ``max_time_s``.

    Args:
        simulation: an existing simulation of ``controller.robot`` (else one is built with
            ``sim_options``, e.g. ``physics_dt_s``, ``payload_kg``, ``effort_scale``).
        max_time_s: stop after this simulated time [s] (default ``10 T_tot + 1 s``).
        on_sample: optional callback ``f(k, simulation, result)`` after each sample (the
            live viewer uses it).

    Ctrl-C or a simulation failure stops the run and keeps the completed samples
    (``interrupted=True`` and a ``note`` in the result).
    """
    robot = controller.robot
    sim = simulation if simulation is not None else MujocoSimulation(robot, **sim_options)
    period = controller.period_s
    steps_per_period = sim.steps_for(period)  # validates that T is a multiple of the step
    del steps_per_period
    duration = controller.trajectory.duration
    limit = (
        10.0 * duration + 1.0
        if max_time_s is None
        else check_positive("max_time_s", max_time_s, "s")
    )
    meas = sim.reset(robot.check_q(q0, "q0"))
    controller.reset(meas.q)
    info = {
        "simulator": "mujoco",
        "controller": controller.name,
        "period_s": period,
        "physics_dt_s": float(sim.model.opt.timestep),
    }
    info.update(meta or {})
    rec = LogRecorder(robot.nq, info)
    interrupted, note, reason = False, "", ""
    num = int(np.ceil(limit / period - 1e-9))
    try:
        for k in range(num):
            result = controller.step(meas.q, meas.qd)
            q_k, qd_k, t_k = meas.q, meas.qd, meas.t_s
            meas = sim.step(result.qd_command, period)
            rec.record(t_k, q_k, qd_k, result, meas.torque, meas.torque_peak)
            if on_sample is not None:
                on_sample(k, sim, result)
            if controller.done:
                break
    except KeyboardInterrupt:
        interrupted, reason = True, "user"
        note = f"interrupted by the user after {len(rec)} samples"
    except DQControlError as exc:
        interrupted, reason = True, "simulation"
        note = f"simulation stopped after {len(rec)} samples: {exc}"
    log = rec.finish()
    if note:
        log.meta["note"] = note
    metrics = compute_metrics(log, controller.trajectory, bounds_of(controller, log.q), period)
    return RunResult(log, metrics, interrupted, note, reason)
