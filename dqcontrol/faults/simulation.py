"""The arm of one campaign case: a driver with the case's faults as wrappers.

The arm is a :class:`~dqcontrol.sim.MujocoDriver` (MuJoCo dynamics, velocity servos) or a
:class:`~dqcontrol.sim.KinematicDriver` (ideal velocity tracking). Around it, innermost
first:

- :class:`~dqcontrol.sim.PayloadDriver` — the fault's unknown payload (MuJoCo only);
- :class:`~dqcontrol.sim.TorqueLimitDriver` — the fault's factor on the torque limits
  (MuJoCo only);
- :class:`~dqcontrol.sim.FaultyDriver` — the fault's measurement noise and delay, always:
  it also records the *true* state (noise-free, undelayed) that the campaign judges.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.experiments.runner import SIMULATORS
from dqcontrol.faults.scenarios import Fault
from dqcontrol.model.robot import RobotModel
from dqcontrol.sim.driver import JointDriver, KinematicDriver, MujocoDriver
from dqcontrol.sim.measurement_faults import FaultyDriver
from dqcontrol.sim.model_faults import PayloadDriver, TorqueLimitDriver

__all__ = ["fault_driver"]


def fault_driver(
    fault: Fault, simulator: str, robot: RobotModel, period_s: float, seed: int = 0
) -> FaultyDriver:
    """The driver of a case: ``simulator``'s arm with ``fault``'s wrappers (module docstring).

    Args:
        fault: the case's fault.
        simulator: ``"mujoco"`` or ``"kinematic"``.
        robot: the controller's robot model.
        period_s: the control period [s].
        seed: seed of the measurement noise.

    Raises:
        ParameterError: an unknown simulator.
        NotASimulatorError: a model fault (payload, torque limits) with the kinematic arm.
    """
    arm: JointDriver
    if simulator == "mujoco":
        arm = MujocoDriver(robot, period_s)
    elif simulator == "kinematic":
        arm = KinematicDriver(robot, period_s)
    else:
        raise ParameterError(f"simulator must be one of {SIMULATORS}, got {simulator!r}")
    if fault.payload_kg > 0.0:
        arm = PayloadDriver(arm, fault.payload_kg, np.asarray(fault.payload_offset_m, dtype=float))
    if fault.effort_scale != 1.0:
        arm = TorqueLimitDriver(arm, fault.effort_scale)
    return FaultyDriver(
        arm,
        q_noise_rad=fault.q_noise_rad,
        qd_noise_rad_s=fault.qd_noise_rad_s,
        delay_periods=fault.delay_periods,
        seed=seed,
    )
