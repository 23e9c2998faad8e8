"""The fault campaign: every controller on every task under every fault, run and judged.

One case is one closed-loop run (:func:`~dqcontrol.sim.run_loop`, the loop of every run)
against the driver of :func:`~dqcontrol.faults.simulation.fault_driver`: a MuJoCo or a
kinematic arm, the model faults (payload, torque limits) and the measurement faults (noise,
delay) as wrappers around it, the outermost recording the *true* state. What is judged:

- **status**: ``completed`` (σ reached ``T_tot``), ``stopped`` (not completed, but the arm
  is at rest at the end: every true joint speed and every command below
  :data:`STOP_SPEED_RAD_S`), ``advancing`` (not at rest, but σ still advanced by at least
  :data:`ADVANCE_FRACTION` of ``T_tot`` over the last :data:`END_SAMPLES` samples: slowed
  down, e.g. by solver failures, yet progressing along the path), ``moving`` (none of these
  at the time limit: the arm moves while the task does not) or ``error`` (the loop raised,
  or the physics became unstable);
- **σ reached**, ``e_mean`` and the path deviation — from the *true* state (noise-free,
  undelayed), so that a noisy sensor does not make the arm look worse or better;
- **bound violations**: commanded velocity and acceleration (the loop's metrics,
  docs/theory.md §9), and joint positions, of the true state (``q_true``) and of what the
  controller measured (``q_meas``, which includes the noise);
- fallbacks and relaxed steps, NaN anywhere, σ monotone, ``0 ≤ s ≤ 1``;
- for contradictory QPs, how often the solver claimed to have solved a QP that has no
  feasible point (``false_successes``).

The QP controllers must have no violation and no NaN; the proportional controller, whose
bounds are only a clip of its command, is reported separately.

The cases and their rows are in :mod:`dqcontrol.faults.cases`, the report in
:mod:`dqcontrol.faults.report`; their names are importable from here too.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from dqcontrol.controllers.base import Controller
from dqcontrol.dq.algebra import dq_from_rt, dq_mul, translation
from dqcontrol.experiments.executor import Executor, resolve_executor
from dqcontrol.experiments.runner import lbr4p
from dqcontrol.experiments.sweep import sweep
from dqcontrol.faults.cases import (
    ADVANCE_FRACTION,
    END_SAMPLES,
    PERIOD_S,
    SIMULATORS,
    STOP_SPEED_RAD_S,
    CampaignResult,
    CaseResult,
    CaseSpec,
    campaign_cases,
)
from dqcontrol.faults.qp_faults import ContradictoryBoundsQP, contradictory
from dqcontrol.faults.report import render_csv, render_markdown
from dqcontrol.faults.scenarios import ControllerSpec, Fault, TrajectorySpec
from dqcontrol.faults.simulation import fault_driver
from dqcontrol.model.robot import RobotModel
from dqcontrol.runs.log import RunLog
from dqcontrol.runs.metrics import VIOLATION_TOL
from dqcontrol.sim.kinematic import RunResult
from dqcontrol.sim.loop import run_loop
from dqcontrol.sim.measurement_faults import FaultyDriver
from dqcontrol.sim.mujoco_sim import SERVO_TIME_CONSTANT_S
from dqcontrol.trajectories.base import Trajectory

__all__ = [
    "ADVANCE_FRACTION",
    "END_SAMPLES",
    "PERIOD_S",
    "SIMULATORS",
    "STOP_SPEED_RAD_S",
    "CampaignResult",
    "CaseResult",
    "CaseSpec",
    "campaign_cases",
    "render_csv",
    "render_markdown",
    "run_campaign",
    "run_case",
    "run_cases",
]


# ----------------------------------------------------------------------------- one case
def run_case(
    spec: CaseSpec,
    *,
    keep_log: bool = False,
    hook: Callable[[Controller], object] | None = None,
) -> CaseResult:
    """Run one case and judge it. Never raises for what happens inside the run: an exception
    is caught and reported in ``raised`` (with ``status = "error"``).

    ``keep_log`` attaches the run log, the true joint positions, the true path deviation
    and the anchored trajectory (for figures). ``hook(controller)`` is called on the
    controller before the run (the what-if experiments of :mod:`dqcontrol.faults.analysis`).
    """
    start_wall = time.perf_counter()
    robot = lbr4p()
    base = _case_fields(spec)
    try:
        controller, driver, result = _simulate(spec, robot, hook)
    except Exception as exc:  # noqa: BLE001 - the campaign reports, it does not stop
        return _error_row(base, exc, start_wall)
    if result.interrupted and result.note.startswith("interrupted by the user"):
        # run_mujoco turns Ctrl-C into a partial run; the campaign must stop, not go on
        raise KeyboardInterrupt
    row, dev = _judge(spec, robot, controller, driver, result, base, start_wall)
    if keep_log:
        row.log, row.true_q, row.path_dev = result.log, driver.true_q, dev
        row.anchored_trajectory = controller.trajectory
    return row


def _case_fields(spec: CaseSpec) -> dict[str, Any]:
    """The fields of a case's row that name the case (the same whatever happens in it)."""
    f, ctrl_spec = spec.fault, spec.controller
    return {
        "fault": f.name,
        "group": f.group,
        "trajectory": spec.trajectory.name,
        "controller": ctrl_spec.name,
        "qp": ctrl_spec.qp,
        "simulator": spec.simulator,
        "duration_s": spec.duration_s,
    }


def _simulate(
    spec: CaseSpec, robot: RobotModel, hook: Callable[[Controller], object] | None
) -> tuple[Controller, FaultyDriver, RunResult]:
    """Build the case (start, trajectory, controller, driver), call ``hook`` on the
    controller and run the closed loop; returns the controller, driver and run."""
    f = spec.fault
    q0 = f.start_configuration(robot)
    traj = _build_trajectory(spec, robot, q0)
    controller = _build_controller(spec, robot, traj)
    if hook is not None:
        hook(controller)
    driver = fault_driver(f, spec.simulator, robot, spec.period_s, spec.seed)
    with _quiet_c_stdout(f.contradiction is not None):
        # no brake after the run: a case is judged in the state its last command led to
        result = run_loop(
            controller,
            driver,
            q0=q0,
            max_time_s=spec.max_time_s,
            meta={"simulator": spec.simulator, "fault": f.name},
            brake=False,
        )
    return controller, driver, result


def _build_trajectory(spec: CaseSpec, robot: RobotModel, q0: np.ndarray):
    """The case's trajectory (the unreachable variant if the fault says so); with the
    fault's reference offset, anchored at the start pose ``robot.pose(q0)`` and shifted."""
    traj = spec.trajectory.build(spec.duration_s, unreachable=spec.fault.unreachable)
    offset = spec.fault.reference_offset_m
    if offset is not None:
        reference = traj.anchored_at(robot.pose(q0)).reference
        assert reference is not None, "an anchored trajectory has its reference"
        shift = dq_from_rt(np.array([1.0, 0.0, 0.0, 0.0]), np.asarray(offset, dtype=float))
        traj = traj.with_reference(dq_mul(shift, reference))
    return traj


def _build_controller(spec: CaseSpec, robot: RobotModel, trajectory) -> Controller:
    """The case's controller, told of the fault as :meth:`Fault.controller_options` says
    and, where it takes it, of the MuJoCo arm's velocity servo (its time constant ``τ_v``);
    solver faults in OSQP's settings, contradictory bounds through
    :func:`~dqcontrol.faults.qp_faults.contradictory`."""
    f, ctrl_spec = spec.fault, spec.controller
    extra: dict = f.controller_options()
    if spec.simulator == "mujoco" and "servo_time_constant_s" in ctrl_spec.takes:
        extra["servo_time_constant_s"] = SERVO_TIME_CONSTANT_S  # the servo it drives
    if ctrl_spec.qp and f.solver_settings:
        extra["solver"] = "osqp"  # the solver faults are written in OSQP's settings
        extra["solver_settings"] = dict(f.solver_settings)
    if ctrl_spec.qp and f.contradiction is not None:
        extra["contradiction"] = f.contradiction
    if "contradiction" in extra or any(k == "contradiction" for k, _ in ctrl_spec.kwargs):
        ctrl_spec = replace(ctrl_spec, cls=contradictory(ctrl_spec.cls))
    return ctrl_spec.build(robot, trajectory, spec.period_s, **extra)


@contextlib.contextmanager
def _quiet_c_stdout(enabled: bool):
    """Send C-level stdout to /dev/null (OSQP prints an ERROR line for every rejected
    update of contradictory bounds)."""
    if not enabled:
        yield
        return
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        yield
        return
    sys.stdout.flush()
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                sys.stdout.flush()
                os.dup2(saved, fd)
    finally:
        os.close(saved)


def _error_row(base: dict[str, Any], exc: Exception, start_wall: float) -> CaseResult:
    """The row of a case whose building or run raised ``exc``: status ``error``, the
    exception in ``raised``, no measurement (NaN) and nothing counted."""
    tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
    nan = float("nan")
    return CaseResult(
        **base, status="error", completed=False, sigma_reached_s=nan, time_s=nan,
        s_mean=nan, s_end=nan, e_mean=nan, path_dev_mean_m=nan, path_dev_max_m=nan,
        path_dev_end_m=nan, speed_end_rad_s=nan, velocity_violations=0,
        acceleration_violations=0, q_violations_true=0, q_excess_true_rad=0.0,
        q_violations_measured=0, q_excess_measured_rad=0.0, fallbacks=0, relaxed_steps=0,
        false_successes=0, nan_seen=False, sigma_monotone=True, s_in_range=True,
        raised=tb, note="", wall_time_s=time.perf_counter() - start_wall,
    )  # fmt: skip


def _judge(
    spec: CaseSpec,
    robot: RobotModel,
    controller: Controller,
    driver: FaultyDriver,
    result: RunResult,
    base: dict[str, Any],
    start_wall: float,
) -> tuple[CaseResult, np.ndarray]:
    """The row of a finished run, judged on the true state (module docstring), and the
    true path deviation of each sample counted by the metrics."""
    log, m = result.log, result.metrics
    k = len(log)
    end = m.samples  # samples counted by the metrics (until σ reached T_tot)
    true_q = driver.true_q  # (k + 1, n): after reset and after every held command
    anchored = controller.trajectory
    # judged on the true state: samples 0..end-1, and the state the last command led to
    q_true_count, q_true_excess = _position_excess(true_q[: end + 1], robot)
    q_meas_count, q_meas_excess = _position_excess(log.q[:end], robot)
    e_mean, dev, dev_end = _tracking(robot, anchored, log, true_q, end)
    speed_end = _speed_end(driver.true_qd, log)
    false_successes = _false_successes(controller)
    nan = float("nan")
    row = CaseResult(
        **base,
        status=_status(result, speed_end, anchored.duration),
        completed=bool(m.completed),
        sigma_reached_s=float(m.sigma_reached_s),
        time_s=float(k * spec.period_s),
        s_mean=float(log.s.mean()) if k else nan,
        s_end=float(log.s[-END_SAMPLES:].mean()) if k else nan,
        e_mean=e_mean,
        path_dev_mean_m=float(dev.mean()) if dev.size else nan,
        path_dev_max_m=float(dev.max()) if dev.size else nan,
        path_dev_end_m=dev_end,
        speed_end_rad_s=speed_end,
        velocity_violations=int(m.velocity_violations),
        acceleration_violations=int(m.acceleration_violations),
        q_violations_true=q_true_count,
        q_excess_true_rad=q_true_excess,
        q_violations_measured=q_meas_count,
        q_excess_measured_rad=q_meas_excess,
        fallbacks=int(np.count_nonzero(log.fallback)),
        relaxed_steps=int(np.count_nonzero(log.relaxed)),
        false_successes=false_successes,
        nan_seen=bool(m.nan_seen or not np.isfinite(true_q).all()),
        sigma_monotone=bool(np.all(np.diff(log.sigma) >= 0.0)),
        s_in_range=bool(np.all((log.s >= 0.0) & (log.s <= 1.0))),
        raised="",
        note=_note(result, false_successes),
        wall_time_s=time.perf_counter() - start_wall,
    )
    return row, dev


def _position_excess(q: np.ndarray, robot: RobotModel) -> tuple[int, float]:
    """How many joint positions of ``q`` lie beyond a limit (by more than the tolerance),
    and the largest excess [rad] (0 if none)."""
    if q.size == 0:
        return 0, 0.0
    lim = robot.limits
    excess = np.maximum(q - lim.q_max, lim.q_min - q)
    return int(np.count_nonzero(excess > VIOLATION_TOL)), float(max(0.0, excess.max()))


def _tracking(
    robot: RobotModel, anchored: Trajectory, log: RunLog, true_q: np.ndarray, end: int
) -> tuple[float, np.ndarray, float]:
    """``e_mean`` (mean pose error to the target), the path deviation of each of the first
    ``end`` samples, and that of the last state, all of the true joint positions; NaN
    and no deviation without samples or with a non-finite true position among them."""
    if not (end and np.isfinite(true_q[:end]).all()):
        return float("nan"), np.zeros(0), float("nan")
    poses = robot.poses(true_q[:end])
    target = log.target[:end]
    flip = (poses * target).sum(axis=1) < 0.0
    poses[flip] *= -1.0
    err = np.linalg.norm(target - poses, axis=1)
    dev = anchored.path_deviation(translation(poses))
    dev_end = float(anchored.path_deviation(translation(robot.pose(true_q[len(log)]))))
    return float(err.mean()), dev, dev_end


def _speed_end(true_qd: np.ndarray, log: RunLog) -> float:
    """The largest joint speed at the end of a run, true or commanded (0 without samples)."""
    if not len(log):
        return 0.0
    return float(max(np.abs(true_qd[-1]).max(), np.abs(log.qd_command[-1]).max()))


def _status(result: RunResult, speed_end: float, duration: float) -> str:
    """The status of a finished run (module docstring); ``duration`` is ``T_tot``."""
    log = result.log
    if result.interrupted:
        return "error"
    if result.metrics.completed:
        return "completed"
    if speed_end < STOP_SPEED_RAD_S:
        return "stopped"
    if len(log) > END_SAMPLES and (
        log.sigma[-1] - log.sigma[-1 - END_SAMPLES] >= ADVANCE_FRACTION * duration
    ):
        return "advancing"
    return "moving"


def _false_successes(controller: Controller) -> int:
    """How often the controller's contradictory QP was reported solved (0 for any other)."""
    qp = getattr(controller, "qp", None)
    return int(qp.false_successes) if isinstance(qp, ContradictoryBoundsQP) else 0


def _note(result: RunResult, false_successes: int) -> str:
    """The row's note: the run's note and the false successes, if any."""
    notes = []
    if result.note:
        notes.append(result.note)
    if false_successes:
        notes.append(f"solver reported 'solved' on {false_successes} infeasible QPs")
    return "; ".join(notes)


# ----------------------------------------------------------------------------- the campaign
def run_campaign(
    controllers: Sequence[str | ControllerSpec] | None = None,
    trajectories: Sequence[str | TrajectorySpec] | None = None,
    faults: Sequence[str | Fault] | None = None,
    simulator: str = "mujoco",
    quick: bool = False,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    seed: int = 0,
    on_result: Callable[[CaseResult, int, int], None] | None = None,
) -> CampaignResult:
    """Run the fault campaign; see :func:`campaign_cases` for the selection.

    Args:
        controllers: the selection of :func:`campaign_cases`, as are ``trajectories``,
            ``faults``, ``simulator`` and ``quick``.
        trajectories: see ``controllers``.
        faults: see ``controllers``.
        simulator: see ``controllers``.
        quick: see ``controllers``.
        workers: processes of the local pool (default: every core; 1 runs in this
            process), or of the local Dask cluster.
        scheduler: a Dask scheduler address, ``"local"`` for a local Dask cluster, or
            ``None`` for the local pool (:mod:`dqcontrol.experiments.executor`).
        seed: seed of the measurement noise.
        on_result: called as ``on_result(row, done, total)`` after each case (progress).

    Ctrl-C stops the campaign: the completed rows are kept and ``interrupted`` is set (the
    note says how many cases ran).
    """
    cases = campaign_cases(controllers, trajectories, faults, simulator, quick, seed)
    executor = resolve_executor(workers, scheduler, len(cases))
    return run_cases(cases, executor, simulator=simulator, quick=quick, on_result=on_result)


def run_cases(
    cases: Sequence[CaseSpec],
    executor: Executor,
    *,
    simulator: str,
    quick: bool = False,
    on_result: Callable[[CaseResult, int, int], None] | None = None,
) -> CampaignResult:
    """Run ``cases`` on ``executor`` (:mod:`dqcontrol.experiments.executor`: this process,
    the local process pool or a Dask cluster) and collect the rows in case order.

    ``simulator`` and ``quick`` label the result. Ctrl-C (or a ``KeyboardInterrupt`` raised
    by ``on_result``) stops the campaign: the completed rows are kept and ``interrupted``
    is set.
    """
    finished = 0

    def progress(index: int, row: CaseResult) -> None:
        nonlocal finished
        finished += 1
        if on_result is not None:
            on_result(row, finished, len(cases))

    outcome = sweep(run_case, cases, executor, on_result=progress)
    rows, interrupted = outcome.results, outcome.interrupted
    note = f"interrupted after {len(rows)} of {len(cases)} cases" if interrupted else ""
    return CampaignResult(
        rows=rows,
        simulator=simulator,
        quick=quick,
        total_cases=len(cases),
        interrupted=interrupted,
        note=note,
        wall_time_s=outcome.wall_time_s,
    )
