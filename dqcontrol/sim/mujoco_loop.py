"""The MuJoCo closed loop: the controller sampled every ``T``, the command held in between.

Per sample k: measure ``(q, qd)`` from the simulation, run one controller step, hold its
command for one period (an integer number of physics steps), record the sample with the
torques applied during that period
(:class:`~dqcontrol.sim.driver.SimulationDriver` in :func:`~dqcontrol.sim.loop.run_loop`).
The log and metrics are those of the kinematic loop.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np

from dqcontrol.controllers.base import Controller
from dqcontrol.sim.driver import SimulationDriver
from dqcontrol.sim.loop import RunResult, run_loop
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
    on_progress: Callable[[float, float], None] | None = None,
    brake: bool = False,
    log_file: str | os.PathLike | None = None,
    **sim_options,
) -> RunResult:
    """Run ``controller`` in MuJoCo from ``q0`` until ``σ ≥ T_tot`` or ``max_time_s``.

    Args:
        controller: the controller to run (reset by the loop).
        q0: start configuration [rad], shape ``(n,)``.
        simulation: an existing simulation of ``controller.robot`` (else one is built with
            ``sim_options``, e.g. ``physics_dt_s``, ``payload_kg``, ``effort_scale``,
            ``motor``).
        max_time_s: stop after this simulated time [s] (default ``10 T_tot + 1 s``).
        meta: added to the log's ``meta`` (as :func:`~dqcontrol.sim.loop.run_loop`).
        on_sample: optional callback ``f(k, simulation, result)`` after each sample (the
            live viewer uses it).
        on_progress: optional callback ``f(σ_next, T_tot)`` [s] after each sample.
        brake: as :func:`~dqcontrol.sim.loop.run_loop` (off: the simulation is left in the
            state the last command led to).
        log_file: stream the log to this ``.mcap`` (as :func:`~dqcontrol.sim.loop.run_loop`).
        **sim_options: keyword arguments of :class:`~dqcontrol.sim.MujocoSimulation`.

    Ctrl-C or a simulation failure stops the run and keeps the completed samples
    (``interrupted=True`` and a ``note`` in the result).
    """
    robot = controller.robot
    sim = simulation if simulation is not None else MujocoSimulation(robot, **sim_options)
    driver = SimulationDriver(sim, controller.period_s)
    follow = None
    if on_sample is not None:

        def follow(k, _driver, result):
            on_sample(k, sim, result)

    return run_loop(
        controller,
        driver,
        q0=q0,
        max_time_s=max_time_s,
        meta=meta,
        on_sample=follow,
        on_progress=on_progress,
        brake=brake,
        log_file=log_file,
    )
