"""Joint drivers: what the control loop reads joint states from and sends velocity commands to.

A :class:`JointDriver` is the boundary between the controller and an arm, simulated or real.
It names its joints (in its own order: the loop maps them to the model's by name), returns
timestamped measurements and takes joint-velocity commands:

- :meth:`JointDriver.read` — the latest :class:`~dqcontrol.sim.Measurement` (time [s], ``q``
  [rad], ``qd`` [rad/s], and the joint torques [N·m] where the driver knows them, NaN
  otherwise);
- :meth:`JointDriver.write` — the velocity command [rad/s] to hold until the next one;
- :meth:`JointDriver.hold` — hold the present position (zero velocity).

A *simulated* driver also has ``period_s`` and ``reset(q0)``: each ``write`` or ``hold`` then
advances the simulation by one period (stepped, simulated time), so a run is deterministic
and as fast as the computer allows. A driver of a real arm keeps its own clock; the loop then
runs in wall-clock time (:func:`~dqcontrol.sim.run_loop` ``realtime=True``).

Drivers here:

- :class:`KinematicDriver` — ideal velocity tracking, ``q_{k+1} = q_k + T u_k``;
- :class:`SimulationDriver` — any simulation object with ``reset``/``step``/``measure``
  (:class:`~dqcontrol.sim.MujocoSimulation`); :class:`MujocoDriver` builds the MuJoCo
  simulation itself (velocity servos by default, computed torque with ``motor="torque"``);
- :class:`VelocityFromPosition` — a velocity driver over a position-only interface
  (:class:`PositionInterface`): it integrates the velocity command into a position target.

Faults are wrappers around these drivers: measurement noise and delay
(:class:`~dqcontrol.sim.FaultyDriver`, :mod:`dqcontrol.sim.measurement_faults`), an unknown
payload and lower torque limits (:class:`~dqcontrol.sim.PayloadDriver`,
:class:`~dqcontrol.sim.TorqueLimitDriver`, :mod:`dqcontrol.sim.model_faults`).
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np

from dqcontrol.errors import ConfigurationError, ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.sim.mujoco_sim import Measurement, MujocoSimulation

__all__ = [
    "JointDriver",
    "JointMismatchError",
    "KinematicDriver",
    "MujocoDriver",
    "PositionInterface",
    "SimulatedDriver",
    "SimulationDriver",
    "VelocityFromPosition",
    "joint_map",
]


class JointMismatchError(ConfigurationError):
    """The driver's joints are not the model's (names, duplicates or count)."""


@runtime_checkable
class JointDriver(Protocol):
    """An arm's joints behind a velocity interface (module docstring)."""

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The driver's joint names, in the order of its arrays."""
        ...

    def read(self) -> Measurement:
        """The latest measurement (driver's joint order)."""
        ...

    def write(self, qd_command: np.ndarray) -> None:
        """Send the joint-velocity command [rad/s] (driver's joint order)."""
        ...

    def hold(self) -> None:
        """Hold the present position (zero velocity)."""
        ...


@runtime_checkable
class SimulatedDriver(JointDriver, Protocol):
    """A driver in simulated time: ``write``/``hold`` advance it by ``period_s``."""

    period_s: float

    def reset(self, q0: np.ndarray) -> Measurement:
        """Put the arm at rest at ``q0`` [rad] (driver's joint order), time 0."""
        ...


@runtime_checkable
class PositionInterface(Protocol):
    """An arm that takes joint-position targets only (e.g. a position-controlled servo bus)."""

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The driver's joint names, in the order of its arrays."""

    def read(self) -> Measurement:
        """The latest measurement (driver's joint order)."""

    def write_position(self, q_target: np.ndarray) -> None:
        """Send joint-position targets [rad] (interface's joint order)."""
        ...


def joint_map(driver_names, model_names) -> np.ndarray | None:
    """Indices ``perm`` with ``q_model = q_driver[perm]``, or ``None`` when the orders agree.

    Raises:
        JointMismatchError: duplicate driver joints, fewer or more joints than the model, or
            names the model does not have; the message lists them.
    """
    drv, mod = [str(n) for n in driver_names], [str(n) for n in model_names]
    dupes = sorted({n for n in drv if drv.count(n) > 1})
    if dupes:
        raise JointMismatchError(f"the driver names joints {dupes} more than once: {drv}")
    missing = [n for n in mod if n not in drv]
    unknown = [n for n in drv if n not in mod]
    if len(drv) < len(mod):
        raise JointMismatchError(
            f"the driver has {len(drv)} joints, the model {len(mod)}: missing {missing} "
            f"(driver: {drv}; model: {mod})"
        )
    if missing or unknown:
        raise JointMismatchError(
            f"joint-name mismatch: the driver has {unknown} that the model has not, and lacks "
            f"{missing} (driver: {drv}; model: {mod})"
        )
    if drv == mod:
        return None
    return np.array([drv.index(n) for n in mod])


def _period(value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"period_s must be a number [s], got {value!r}") from None
    if not math.isfinite(v) or v <= 0.0:
        raise ParameterError(f"period_s must be finite and > 0 [s], got {value!r}")
    return v


class KinematicDriver:
    """Ideal velocity tracking in simulated time: ``q ← q + T u``, ``qd ← u``, ``t = k T``.

    Args:
        robot: the robot (its joint names, count and configuration checks).
        period_s: ``T`` [s], the time one ``write`` or ``hold`` advances.

    Torques are NaN (no dynamics).
    """

    #: The joints reach each command at once (no servo lag).
    ideal_tracking = True

    def __init__(self, robot: RobotModel, period_s: float) -> None:
        if not isinstance(robot, RobotModel):
            raise ParameterError(f"robot must be a RobotModel, got {type(robot).__name__}")
        self.robot = robot
        self.period_s = _period(period_s)
        self.joint_names = tuple(robot.joint_names)
        n = robot.nq
        self._q = np.zeros(n)
        self._qd = np.zeros(n)
        self._k = 0
        self._nan = np.full(n, np.nan)

    #: What the loop writes to the log's ``meta``.
    meta = property(lambda self: {"simulator": "kinematic"})

    def reset(self, q0: np.ndarray) -> Measurement:
        """At rest at ``q0`` [rad], time 0."""
        self._q = self.robot.check_q(q0, "q0").copy()
        self._qd = np.zeros(self.robot.nq)
        self._k = 0
        return self.read()

    def read(self) -> Measurement:
        """The state after the last period (velocity: the command held)."""
        return Measurement(self._k * self.period_s, self._q, self._qd, self._nan, self._nan)

    def write(self, qd_command: np.ndarray) -> None:
        """Hold ``qd_command`` [rad/s] for one period (exact integration).

        Raises:
            ConfigurationError: ``qd_command`` has the wrong shape or is not finite.
        """
        u = self.robot.check_q(qd_command, "qd_command")
        self._q = self._q + self.period_s * u
        self._qd = u.copy()
        self._k += 1

    def hold(self) -> None:
        """Stand still for one period."""
        self.write(np.zeros(self.robot.nq))

    def __repr__(self) -> str:
        return f"KinematicDriver(n={self.robot.nq}, T={self.period_s} s)"


class SimulationDriver:
    """A simulation object behind the driver protocol, in simulated time.

    Args:
        simulation: an object with ``robot``, ``reset(q0)``, ``step(qd, duration_s)``,
            ``measure()``, ``steps_for(duration_s)`` and ``model.opt.timestep``
            (:class:`~dqcontrol.sim.MujocoSimulation` or a wrapper of it).
        period_s: the control period [s], a whole number of the simulation's steps.

    Raises:
        ParameterError: ``period_s`` is not a whole number of physics steps.
    """

    def __init__(self, simulation, period_s: float) -> None:
        for member in ("reset", "step", "measure", "steps_for", "robot"):
            if not hasattr(simulation, member):
                raise ParameterError(
                    f"simulation must have reset/step/measure/steps_for/robot; "
                    f"{type(simulation).__name__} has no '{member}'"
                )
        self.simulation = simulation
        self.period_s = _period(period_s)
        simulation.steps_for(self.period_s)  # validates: a whole number of physics steps
        self.joint_names = tuple(simulation.robot.joint_names)
        self._last: Measurement | None = None

    @property
    def meta(self) -> dict:
        """``simulator`` and ``physics_dt_s`` for the run log."""
        return {"simulator": "mujoco", "physics_dt_s": float(self.simulation.model.opt.timestep)}

    def reset(self, q0: np.ndarray) -> Measurement:
        """Reset the simulation at rest at ``q0`` [rad]."""
        self._last = self.simulation.reset(q0)
        return self._last

    def read(self) -> Measurement:
        """The measurement after the last period."""
        if self._last is None:
            self._last = self.simulation.measure()
        return self._last

    def write(self, qd_command: np.ndarray) -> None:
        """Hold ``qd_command`` [rad/s] for one period."""
        self._last = self.simulation.step(qd_command, self.period_s)

    def hold(self) -> None:
        """Command zero velocity for one period."""
        self.write(np.zeros(len(self.joint_names)))

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.simulation!r}, T={self.period_s} s)"


class MujocoDriver(SimulationDriver):
    """The robot in MuJoCo (:class:`~dqcontrol.sim.MujocoSimulation`) as a driver.

    Args:
        robot: the controller's robot model.
        period_s: the control period [s].
        sim_options: :class:`~dqcontrol.sim.MujocoSimulation`'s keywords (``motor``,
            ``physics_dt_s``, ``obstacles`` ...); an unknown payload and lower torque limits
            are the wrappers :class:`~dqcontrol.sim.PayloadDriver` and
            :class:`~dqcontrol.sim.TorqueLimitDriver`.
    """

    def __init__(self, robot: RobotModel, period_s: float, **sim_options) -> None:
        super().__init__(MujocoSimulation(robot, **sim_options), period_s)

    @property
    def meta(self) -> dict:
        """``simulator``, ``physics_dt_s`` and the joint drive (``motor``) for the run log."""
        return {**super().meta, "motor": self.simulation.motor}


class VelocityFromPosition:
    """A velocity driver over a position-only interface: it sends ``q_target += T u``.

    The target starts at the first measured position (or at ``reset``'s ``q0``) and
    integrates the velocity commands; :meth:`hold` resends the present target.

    Args:
        inner: the position interface (:class:`PositionInterface`).
        period_s: ``T`` [s], the time one command is held.
    """

    def __init__(self, inner: PositionInterface, period_s: float) -> None:
        for member in ("joint_names", "read", "write_position"):
            if not hasattr(inner, member):
                raise ParameterError(
                    f"inner must have joint_names/read/write_position; "
                    f"{type(inner).__name__} has no '{member}'"
                )
        self.inner = inner
        self.period_s = _period(period_s)
        self.joint_names = tuple(inner.joint_names)
        self._target: np.ndarray | None = None

    @property
    def meta(self) -> dict:
        """The inner driver's description, with ``interface: position``."""
        return {**getattr(self.inner, "meta", {}), "interface": "position"}

    @property
    def target(self) -> np.ndarray | None:
        """The position target [rad] sent last (``None`` before the first read)."""
        return None if self._target is None else self._target.copy()

    def reset(self, q0: np.ndarray) -> Measurement:
        """Reset the inner interface (it must have ``reset``) and the target at ``q0``."""
        if not hasattr(self.inner, "reset"):
            raise ParameterError(
                f"{type(self.inner).__name__} cannot be reset (a real arm starts where it is)"
            )
        meas = self.inner.reset(q0)
        self._target = np.array(meas.q, dtype=float)
        return meas

    def read(self) -> Measurement:
        """The inner driver's measurement."""
        meas = self.inner.read()
        if self._target is None:
            self._target = np.array(meas.q, dtype=float)
        return meas

    def write(self, qd_command: np.ndarray) -> None:
        """Move the position target by ``T qd_command`` and send it."""
        self._target = self._current_target() + self.period_s * np.asarray(qd_command, dtype=float)
        self.inner.write_position(self._target)

    def hold(self) -> None:
        """Send the present target again."""
        self.inner.write_position(self._current_target())

    def _current_target(self) -> np.ndarray:
        """The position target [rad]: the measured ``q`` until a command moves it."""
        if self._target is None:
            return np.array(self.read().q, dtype=float)  # read() sets it
        return self._target

    def __repr__(self) -> str:
        return f"VelocityFromPosition({self.inner!r}, T={self.period_s} s)"
