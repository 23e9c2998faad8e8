"""One experiment case: the robot, the trajectory and the controller built from names and
numbers, run in the chosen closed loop, and measured.

Table 1 (:mod:`dqcontrol.experiments.table1`) and the studies run their cases through
here (the fault campaign builds its own faulty drivers, :mod:`dqcontrol.faults.simulation`,
and shares the robot and trajectories):

- :func:`lbr4p` — the experiments' robot, loaded once per thread;
- :func:`build_trajectory` — a trajectory from its metadata
  (:func:`~dqcontrol.trajectories.trajectory_from_metadata`);
- :func:`~dqcontrol.registry.build_controller` — a controller by name (re-exported);
- :func:`simulate` — the closed loop (:func:`~dqcontrol.sim.run_loop` with the kinematic or
  the MuJoCo driver, or any simulation object), with the metrics
  of docs/theory.md §9 and, on request, the path deviation *between* the control samples:
  along MuJoCo's physics steps, or along the straight joint-space motion of the kinematic
  loop;
- :func:`time_optimal_duration` — the TOPP-RA lower bound of the task's execution time
  (:mod:`dqcontrol.experiments.time_optimal`), cached per process, NaN with a note when it
  cannot be computed.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from dqcontrol.controllers.base import Controller
from dqcontrol.dq.algebra import translation
from dqcontrol.errors import DQControlError, ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.registry import build_controller
from dqcontrol.sim.driver import KinematicDriver, SimulationDriver
from dqcontrol.sim.loop import RunResult, run_loop
from dqcontrol.sim.mujoco_sim import Measurement, MujocoSimulation
from dqcontrol.trajectories import Trajectory, trajectory_from_metadata

__all__ = [
    "SIMULATORS",
    "CaseRun",
    "build_controller",
    "build_trajectory",
    "lbr4p",
    "simulate",
    "time_optimal_duration",
]

#: The closed loops a case can run in.
SIMULATORS = ("mujoco", "kinematic")
#: Points per control period at which the kinematic loop's motion is sampled between samples.
KINEMATIC_SUBSAMPLES = 10

_LOCAL = threading.local()


def lbr4p() -> RobotModel:
    """The LBR4p, loaded once per thread (the loops only read the model, but its Pinocchio
    workspace is shared by every call, so threads must not share it)."""
    robot = getattr(_LOCAL, "robot", None)
    if robot is None:
        from dqcontrol.model.library import load_lbr4p

        robot = _LOCAL.robot = load_lbr4p()
    return robot


def build_trajectory(meta: Mapping) -> Trajectory:
    """The (unanchored unless ``meta`` has a reference) trajectory ``meta`` describes."""
    return trajectory_from_metadata(meta)


# ---------------------------------------------------------------------------- the loop
@dataclass(frozen=True)
class CaseRun:
    """A finished case.

    Attributes:
        result: the loop's :class:`~dqcontrol.sim.RunResult` (log and metrics).
        controller: the controller, after the run (its trajectory is the anchored one).
        between_deviation_max_m: largest path deviation [m] over the states between
            consecutive control samples of the task (those the metrics count, the samples
            included), NaN if not measured.
        wall_time_s: wall time of the loop and of the measurements [s].
    """

    result: RunResult
    controller: Controller
    between_deviation_max_m: float
    wall_time_s: float


class _PhysicsStepRecorder:
    """A MuJoCo simulation that keeps the joint positions after every physics step.

    Holding a command for a period is the same as holding it for each of the period's
    physics steps in turn (:meth:`MujocoSimulation.step` sets the command and advances;
    nothing else changes between calls), so the run is unchanged; the measurement returned
    carries the peak torque over the whole period, as the wrapped simulation's would.
    """

    def __init__(self, inner: MujocoSimulation) -> None:
        self.inner = inner
        self.dt_s = float(inner.physics_dt_s)
        self.positions: list[list[np.ndarray]] = []  # per held period, after each step

    model = property(lambda self: self.inner.model)
    data = property(lambda self: self.inner.data)

    def steps_for(self, duration_s: float) -> int:
        return self.inner.steps_for(duration_s)

    def __getattr__(self, name: str):
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    def reset(self, q0: np.ndarray, qd0: np.ndarray | None = None) -> Measurement:
        self.positions = []
        return self.inner.reset(q0, qd0)

    def step(self, qd_command: np.ndarray, duration_s: float) -> Measurement:
        steps = self.inner.steps_for(duration_s)
        period: list[np.ndarray] = []
        peak = None
        for _ in range(steps):
            meas = self.inner.step(qd_command, self.dt_s)
            period.append(meas.q)
            peak = meas.torque_peak if peak is None else np.maximum(peak, meas.torque_peak)
        self.positions.append(period)
        assert peak is not None, "a period has at least one physics step"
        return Measurement(meas.t_s, meas.q, meas.qd, meas.torque, peak)


def simulate(
    controller: Controller,
    q0: np.ndarray,
    simulator: str = "mujoco",
    *,
    simulation=None,
    max_time_s: float | None = None,
    meta: dict | None = None,
    between_samples: bool = False,
) -> CaseRun:
    """Run ``controller`` from ``q0`` [rad] until the task is done or ``max_time_s``.

    Args:
        controller: the controller to run (reset by the loop).
        q0: start configuration [rad], shape ``(n,)``.
        simulator: ``"mujoco"`` (the default :class:`~dqcontrol.sim.MujocoSimulation`) or
            ``"kinematic"`` (:class:`~dqcontrol.sim.KinematicDriver`).
        simulation: a simulation object to run instead (any object with MuJoCo's
            ``reset/step/measure/steps_for/model`` members,
            :class:`~dqcontrol.sim.SimulationDriver`).
        max_time_s: as for the loops (:func:`~dqcontrol.sim.loop.run_loop`).
        meta: as for the loops.
        between_samples: also measure the path deviation between the control samples
            (:attr:`CaseRun.between_deviation_m`): after every physics step in MuJoCo, at
            :data:`KINEMATIC_SUBSAMPLES` points per period in the kinematic loop (where the
            joints move in straight lines over a period). Ignored with ``simulation``.
    """
    if simulator not in SIMULATORS:
        raise ParameterError(f"simulator must be one of {SIMULATORS}, got {simulator!r}")
    start = time.perf_counter()
    recorder = None
    period = controller.period_s
    driver: SimulationDriver | KinematicDriver
    if simulation is not None:
        driver = SimulationDriver(simulation, period)
    elif simulator == "kinematic":
        driver = KinematicDriver(controller.robot, period)
    else:
        mujoco_sim = MujocoSimulation(controller.robot)
        sim: MujocoSimulation | _PhysicsStepRecorder = mujoco_sim
        if between_samples:
            recorder = sim = _PhysicsStepRecorder(mujoco_sim)
        driver = SimulationDriver(sim, period)
    # no brake after the run: a case is judged in the state its last command led to
    result = run_loop(controller, driver, q0=q0, max_time_s=max_time_s, meta=meta, brake=False)
    between = math.nan
    if between_samples and simulation is None:
        between = _largest_deviation(controller, _between_states(controller, result, recorder))
    return CaseRun(result, controller, between, time.perf_counter() - start)


def _between_states(controller: Controller, result: RunResult, recorder) -> np.ndarray:
    """Joint positions over each period between consecutive samples the metrics count,
    ``(K, m + 1, n)``: the sample, then the states within the period, the last being the
    next sample. The period after the last sample, in which σ passes ``T_tot`` and the arm
    moves on beyond the path's end, is not included."""
    intervals = max(result.metrics.samples - 1, 0)
    log = result.log
    n = controller.robot.nq
    if intervals == 0:
        return np.zeros((0, 1, n))
    if recorder is not None:
        within = np.asarray(recorder.positions[:intervals]).reshape(intervals, -1, n)
        return np.concatenate((log.q[:intervals, None, :], within), axis=1)
    fractions = np.arange(KINEMATIC_SUBSAMPLES + 1) / KINEMATIC_SUBSAMPLES
    steps = controller.period_s * log.qd_command[:intervals]
    return log.q[:intervals, None, :] + fractions[None, :, None] * steps[:, None, :]


def _largest_deviation(controller: Controller, states: np.ndarray) -> float:
    """The largest path deviation [m] over ``states`` ``(K, m + 1, n)`` (periods whose first
    and last states are samples).

    Exact, but measured only where it can exceed the samples' largest: a state's deviation
    is at most a sample's plus its distance from that sample, so a state whose bound from
    both ends of its period is below the samples' largest cannot be the maximum.
    """
    if states.size == 0 or not np.isfinite(states).all():
        return math.nan
    k, m, n = states.shape
    path = controller.trajectory
    points = translation(controller.robot.poses(states.reshape(-1, n))).reshape(k, m, 3)
    first = np.asarray(path.path_deviation(points[:, 0]))
    last = np.asarray(path.path_deviation(points[:, -1]))
    best = float(max(first.max(), last.max()))
    reach = np.minimum(
        first[:, None] + np.linalg.norm(points - points[:, :1], axis=2),
        last[:, None] + np.linalg.norm(points - points[:, -1:], axis=2),
    )
    candidates = points[reach > best]
    if candidates.size:
        best = max(best, float(np.max(path.path_deviation(candidates))))
    return best


# ---------------------------------------------------------------------------- the bound
_BOUNDS: dict[str, tuple[float, str]] = {}


def time_optimal_duration(
    robot: RobotModel,
    trajectory: Trajectory,
    q0: np.ndarray,
    **constraints,
) -> tuple[float, str]:
    """The TOPP-RA lower bound of ``trajectory``'s execution time from rest at ``q0``.

    ``constraints`` are :func:`~dqcontrol.experiments.time_optimal.time_optimal_bound`'s
    keywords (limits, speed cap, posture gain, samples). Computed once per process for the
    same robot, task, start and constraints.

    Returns:
        ``(duration [s], note)``: the note is empty, or says why the duration is NaN
        (``toppra`` not installed, a task the joint path cannot follow, ...). Never raises
        for these.
    """
    from dqcontrol.experiments.time_optimal import time_optimal_bound

    key = json.dumps(
        [
            robot.model.name,
            robot.ee_frame,
            trajectory.to_metadata(),
            np.asarray(q0, dtype=float).tolist(),
            {k: _plain(v) for k, v in sorted(constraints.items())},
        ]
    )
    cached = _BOUNDS.get(key)
    if cached is None:
        try:
            bound = time_optimal_bound(robot, trajectory, q0, **constraints)
            cached = (bound.duration_s, "")
        except DQControlError as exc:
            cached = (math.nan, f"no time-optimal bound: {exc}")
        _BOUNDS[key] = cached
    return cached


def _plain(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value
