"""Fault injection around a simulation: measurement noise and measurement delay.

The control loop (:func:`~dqcontrol.sim.run_loop`, through
:class:`~dqcontrol.sim.SimulationDriver`) talks to a simulation through five members —
``reset``, ``step``, ``measure``, ``steps_for`` and ``model`` (plus ``data`` for a viewer).
:class:`FaultySimulation` wraps any object with these members and corrupts what the
controller *sees*, never the physics (the same faults around any joint driver:
:class:`~dqcontrol.sim.FaultyDriver`):

- seeded Gaussian noise on the measured joint positions and velocities;
- a measurement delay of ``d`` control periods: the controller receives the joint positions
  and velocities measured ``d`` periods ago (a FIFO of :class:`~dqcontrol.sim.Measurement`),
  stamped with the current time so that the loop's clock and log stay on time.

It also keeps the *true* (noise-free, undelayed) measurement of every period, so that a
campaign can judge what the arm really did (joint limits, path deviation) rather than what
the corrupted sensors reported.

:class:`KinematicSimulation` is the ideal velocity loop of
:func:`~dqcontrol.sim.run_kinematic` (``q_{k+1} = q_k + T qd_k``) with the same duck-typed
interface, so that the same wrapper and the same loop serve both simulators. Model faults
(an unknown payload, reduced torque limits) are options of
:class:`~dqcontrol.sim.MujocoSimulation` itself (``payload_kg``, ``effort_scale``).
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.sim.driver import MeasurementFaults, true_copy
from dqcontrol.sim.mujoco_sim import Measurement

__all__ = ["FaultySimulation", "KinematicSimulation"]


def _non_negative(name: str, value: float, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number [{unit}], got {value!r}") from None
    if not math.isfinite(v) or v < 0.0:
        raise ParameterError(f"{name} must be finite and ≥ 0 [{unit}], got {value!r}")
    return v


class KinematicSimulation:
    """Ideal velocity tracking behind the simulation interface: ``q ← q + Δt · qd``.

    Args:
        robot: the robot model (only its joint count and checks are used).
        period_s: the integration step [s] (the control period; ``step`` accepts any whole
            multiple of it).

    The measured velocity is the command being held; torques are NaN (no dynamics).
    """

    def __init__(self, robot: RobotModel, period_s: float) -> None:
        if not isinstance(robot, RobotModel):
            raise ParameterError(f"robot must be a RobotModel, got {type(robot).__name__}")
        dt = _non_negative("period_s", period_s, "s")
        if dt == 0.0:
            raise ParameterError(f"period_s must be > 0 [s], got {period_s!r}")
        self.robot = robot
        self.physics_dt_s = dt
        # what run_mujoco reads for its log's meta (``model.opt.timestep``)
        self._model = SimpleNamespace(opt=SimpleNamespace(timestep=dt))
        n = robot.nq
        self._q = np.zeros(n)
        self._qd = np.zeros(n)
        self._t = 0.0
        self._nan = np.full(n, np.nan)

    @property
    def model(self) -> SimpleNamespace:
        """A stand-in with ``opt.timestep`` (the loops read it for their log)."""
        return self._model

    @property
    def data(self) -> SimpleNamespace:
        """The state, as ``qpos``/``qvel`` arrays (copies)."""
        return SimpleNamespace(qpos=self._q.copy(), qvel=self._qd.copy(), time=self._t)

    def steps_for(self, duration_s: float) -> int:
        """Whole number of integration steps in ``duration_s`` [s] (ParameterError if not)."""
        duration = _non_negative("duration_s", duration_s, "s")
        steps = round(duration / self.physics_dt_s)
        if steps < 1 or abs(duration - steps * self.physics_dt_s) > 1e-9:
            raise ParameterError(
                f"duration_s={duration!r} is not a whole number of steps of {self.physics_dt_s} s"
            )
        return steps

    def reset(self, q0: np.ndarray, qd0: np.ndarray | None = None) -> Measurement:
        """Put the arm at ``q0`` [rad] with velocity ``qd0`` [rad/s] (default 0), time 0."""
        self._q = self.robot.check_q(q0, "q0").copy()
        self._qd = np.zeros(self.robot.nq) if qd0 is None else self.robot.check_q(qd0, "qd0").copy()
        self._t = 0.0
        return self.measure()

    def step(self, qd_command: np.ndarray, duration_s: float) -> Measurement:
        """Hold ``qd_command`` [rad/s] for ``duration_s`` [s] (exact integration)."""
        u = self.robot.check_q(qd_command, "qd_command")
        steps = self.steps_for(duration_s)
        dt = steps * self.physics_dt_s
        self._q = self._q + dt * u
        self._qd = u.copy()
        self._t += dt
        return self.measure()

    def measure(self) -> Measurement:
        """The current state (no noise: wrap in :class:`FaultySimulation` for that)."""
        return Measurement(
            t_s=self._t,
            q=self._q.copy(),
            qd=self._qd.copy(),
            torque=self._nan.copy(),
            torque_peak=self._nan.copy(),
        )

    def __repr__(self) -> str:
        return f"KinematicSimulation(n={self.robot.nq}, dt={self.physics_dt_s} s)"


class FaultySimulation:
    """A simulation whose measurements are noisy and/or delayed.

    The simulation-interface twin of :class:`~dqcontrol.sim.driver.FaultyDriver`: the same
    faults (:class:`~dqcontrol.sim.driver.MeasurementFaults`) around an object with
    ``reset``/``step``/``measure``, for the loops that take a simulation.

    Args:
        inner: the simulation to wrap (:class:`~dqcontrol.sim.MujocoSimulation`,
            :class:`KinematicSimulation`, or anything with the same members).
        q_noise_rad: standard deviation of the Gaussian noise on each measured joint
            position [rad] (e.g. 0.002 = 2 mrad), ≥ 0.
        qd_noise_rad_s: standard deviation of the noise on each measured joint velocity
            [rad/s], ≥ 0.
        delay_periods: the controller receives the measurement taken this many ``step``
            calls (control periods) ago; an integer ≥ 0. Before that many periods have
            passed it receives the initial measurement.
        seed: seed of the noise generator; :meth:`reset` restarts the same sequence.

    Attributes:
        true_measurements: the noise-free, undelayed measurement after :meth:`reset` and
            after every :meth:`step` (what really happened).
    """

    def __init__(
        self,
        inner,
        *,
        q_noise_rad: float = 0.0,
        qd_noise_rad_s: float = 0.0,
        delay_periods: int = 0,
        seed: int = 0,
    ) -> None:
        for member in ("reset", "step", "measure", "steps_for", "model"):
            if not hasattr(inner, member):
                raise ParameterError(
                    f"inner must be a simulation with reset/step/measure/steps_for/model; "
                    f"{type(inner).__name__} has no '{member}'"
                )
        self.inner = inner
        self.faults = MeasurementFaults(q_noise_rad, qd_noise_rad_s, delay_periods, seed)
        self._last: Measurement | None = None
        self.true_measurements: list[Measurement] = []

    q_noise_rad = property(lambda self: self.faults.q_noise_rad)
    qd_noise_rad_s = property(lambda self: self.faults.qd_noise_rad_s)
    delay_periods = property(lambda self: self.faults.delay_periods)
    seed = property(lambda self: self.faults.seed)

    # ------------------------------------------------------------------ delegated members
    @property
    def model(self):
        """The wrapped simulation's model."""
        return self.inner.model

    @property
    def data(self):
        """The wrapped simulation's data (the true state)."""
        return self.inner.data

    def steps_for(self, duration_s: float) -> int:
        """As the wrapped simulation's ``steps_for``."""
        return self.inner.steps_for(duration_s)

    def __getattr__(self, name: str):
        # anything else (ee_pose, robot, time_s ...) comes from the wrapped simulation
        if name in ("inner", "faults"):  # not set yet (during unpickling)
            raise AttributeError(name)
        return getattr(self.inner, name)

    # ------------------------------------------------------------------ the faults
    @property
    def true_q(self) -> np.ndarray:
        """True joint positions [rad] after reset and after every step, ``(K + 1, n)``."""
        return np.array([m.q for m in self.true_measurements])

    @property
    def true_qd(self) -> np.ndarray:
        """True joint velocities [rad/s], ``(K + 1, n)``."""
        return np.array([m.qd for m in self.true_measurements])

    def _record(self, m: Measurement) -> Measurement:
        true = true_copy(m)
        self.true_measurements.append(true)
        return true

    def reset(self, q0: np.ndarray, qd0: np.ndarray | None = None) -> Measurement:
        """Reset the wrapped simulation, the noise sequence and the delay line."""
        self.true_measurements = []
        self._last = self.faults.restart(self._record(self.inner.reset(q0, qd0)))
        return self._last

    def step(self, qd_command: np.ndarray, duration_s: float) -> Measurement:
        """Step the wrapped simulation; return the delayed, noisy measurement."""
        self._last = self.faults.push(self._record(self.inner.step(qd_command, duration_s)))
        return self._last

    def measure(self) -> Measurement:
        """The measurement the controller received last (delayed, noisy)."""
        if self._last is None:  # before the first reset: the current state, noisy
            now = self.inner.measure()
            return self.faults.observe(now, now)
        return self._last

    def __repr__(self) -> str:
        return (
            f"FaultySimulation({self.inner!r}, q_noise_rad={self.q_noise_rad}, "
            f"qd_noise_rad_s={self.qd_noise_rad_s}, delay_periods={self.delay_periods}, "
            f"seed={self.seed})"
        )
