"""Model faults around a simulated driver: the arm differs from the controller's model.

- :class:`PayloadDriver` — a mass at the flange that neither the controller's model nor the
  drives' nominal model knows (e.g. 3 kg at 5 cm);
- :class:`TorqueLimitDriver` — every drive's torque limit multiplied by a factor (0.5
  halves them).

They wrap any driver whose ``simulation`` can change its physics
(:class:`DynamicSimulation`: :class:`~dqcontrol.sim.MujocoSimulation`, behind
:class:`~dqcontrol.sim.MujocoDriver`, or behind another wrapper of this module or
:class:`~dqcontrol.sim.FaultyDriver`). The change is made to that simulation when the
wrapper is built and lasts as long as it; commands and measurements pass through unchanged.
A driver without such a simulation (the kinematic driver, a bridge to another process, a
real arm) raises :class:`NotASimulatorError`.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from dqcontrol.errors import ConfigurationError, ParameterError
from dqcontrol.sim.driver import JointDriver, SimulatedDriver
from dqcontrol.sim.mujoco_sim import Measurement

__all__ = [
    "DynamicSimulation",
    "NotASimulatorError",
    "PayloadDriver",
    "TorqueLimitDriver",
    "dynamic_simulation",
]


@runtime_checkable
class DynamicSimulation(Protocol):
    """A simulation whose arm can carry an unknown payload and have its torque limits
    scaled, keeping its state (:class:`~dqcontrol.sim.MujocoSimulation`)."""

    @property
    def payload_kg(self) -> float:
        """Mass carried at the flange, unknown to the controller [kg] (0: none)."""
        ...

    effort_scale: float

    def set_payload(self, mass_kg: float, offset_m: np.ndarray | None = None) -> None:
        """Carry ``mass_kg`` [kg] at ``offset_m`` [m] in the end-effector frame."""
        ...

    def set_effort_scale(self, scale: float) -> None:
        """Limit every drive's torque to ``scale`` × its nominal limit."""
        ...


class NotASimulatorError(ConfigurationError):
    """A model fault was asked of a driver that has no simulation whose physics it can
    change."""


def dynamic_simulation(driver: JointDriver, fault: str) -> DynamicSimulation:
    """The simulation behind ``driver`` that ``fault`` (a wrapper's name) will change.

    Raises:
        NotASimulatorError: ``driver`` has no ``simulation``, or its simulation is not a
            :class:`DynamicSimulation`; the message names both and what is missing.
    """
    sim = getattr(driver, "simulation", None)
    if isinstance(sim, DynamicSimulation):
        return sim
    if sim is None:
        why = "it has no simulation (e.g. an ideal kinematic arm, a bridge or a real arm)"
    else:
        missing = [
            name
            for name in ("payload_kg", "effort_scale", "set_payload", "set_effort_scale")
            if not hasattr(sim, name)
        ]
        why = f"its simulation, a {type(sim).__name__}, has no {missing}"
    raise NotASimulatorError(
        f"{fault} needs a driver over a dynamic simulation that can carry a payload and "
        f"change its torque limits (e.g. MujocoDriver); {type(driver).__name__} cannot: {why}"
    )


class _ModelFault:
    """A driver that passes everything to ``inner`` and owns a change of its simulation."""

    def __init__(self, inner: JointDriver) -> None:
        if not isinstance(inner, JointDriver):
            raise ParameterError(
                f"inner must be a JointDriver (joint_names/read/write/hold), got "
                f"{type(inner).__name__}"
            )
        #: The simulation this fault changed (the wrapped driver's).
        self.simulation = dynamic_simulation(inner, type(self).__name__)
        self.inner = inner
        self.joint_names = tuple(inner.joint_names)
        self.period_s = getattr(inner, "period_s", None)

    def _meta(self) -> dict:
        return {}

    @property
    def meta(self) -> dict:
        """The wrapped driver's entries and the fault's, for the run log."""
        return {**getattr(self.inner, "meta", {}), **self._meta()}

    def reset(self, q0: np.ndarray) -> Measurement:
        """Reset the wrapped driver at ``q0`` [rad] (the fault stays)."""
        if not isinstance(self.inner, SimulatedDriver):
            raise ParameterError(
                f"only a simulated driver resets; {type(self.inner).__name__} has no reset"
            )
        return self.inner.reset(q0)

    def read(self) -> Measurement:
        return self.inner.read()

    def write(self, qd_command: np.ndarray) -> None:
        self.inner.write(qd_command)

    def hold(self) -> None:
        self.inner.hold()


class PayloadDriver(_ModelFault):
    """The wrapped driver's arm carries ``mass_kg`` that the controller does not know.

    Args:
        inner: a driver over a :class:`DynamicSimulation` (e.g.
            :class:`~dqcontrol.sim.MujocoDriver`) that carries no payload yet.
        mass_kg: the payload [kg], > 0.
        offset_m: its centre in the end-effector frame [m] (default: at the frame).

    Raises:
        NotASimulatorError: ``inner`` has no such simulation.
        ConfigurationError: its simulation already carries a payload.
        ParameterError: a mass that is not finite and > 0, an offset that is not 3 finite
            numbers.
    """

    def __init__(
        self, inner: JointDriver, mass_kg: float, offset_m: np.ndarray | None = None
    ) -> None:
        super().__init__(inner)
        sim = self.simulation
        if sim.payload_kg > 0.0:
            raise ConfigurationError(
                f"{type(inner).__name__}'s simulation already carries a payload of "
                f"{sim.payload_kg} kg; give one PayloadDriver the total mass"
            )
        if isinstance(mass_kg, bool) or not (
            isinstance(mass_kg, int | float | np.floating) and mass_kg > 0.0
        ):
            raise ParameterError(f"mass_kg must be a number > 0 [kg], got {mass_kg!r}")
        sim.set_payload(float(mass_kg), offset_m)
        self.mass_kg = float(mass_kg)
        self.offset_m = np.zeros(3) if offset_m is None else np.array(offset_m, dtype=float)

    def _meta(self) -> dict:
        return {"payload_kg": self.mass_kg, "payload_offset_m": self.offset_m.tolist()}

    def __repr__(self) -> str:
        return f"PayloadDriver({self.inner!r}, mass_kg={self.mass_kg}, offset_m={self.offset_m})"


class TorqueLimitDriver(_ModelFault):
    """The wrapped driver's torque limits multiplied by ``scale`` (0.5 halves them).

    Args:
        inner: a driver over a :class:`DynamicSimulation` (e.g.
            :class:`~dqcontrol.sim.MujocoDriver`).
        scale: factor on the present limits, > 0 (wrappers compose: two halvings leave a
            quarter).

    Raises:
        NotASimulatorError: ``inner`` has no such simulation.
        ParameterError: ``scale`` is not finite and > 0.
    """

    def __init__(self, inner: JointDriver, scale: float = 0.5) -> None:
        super().__init__(inner)
        if isinstance(scale, bool) or not (
            isinstance(scale, int | float | np.floating) and np.isfinite(scale)
        ):
            raise ParameterError(f"scale must be a finite number > 0, got {scale!r}")
        if scale <= 0.0:
            raise ParameterError(f"scale must be > 0, got {scale!r}")
        self.scale = float(scale)
        self.simulation.set_effort_scale(self.simulation.effort_scale * self.scale)

    def _meta(self) -> dict:
        return {"effort_scale": float(self.simulation.effort_scale)}

    def __repr__(self) -> str:
        return f"TorqueLimitDriver({self.inner!r}, scale={self.scale})"
