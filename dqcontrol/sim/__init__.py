"""Closed loops: one control loop (:func:`run_loop`) against a joint driver — ideal kinematic,
MuJoCo, a position-only interface, fault wrappers (measurement noise and delay, an unknown
payload, lower torque limits, a real arm's reflexes: :class:`ReflexDriver`) or a simulation
in another process (:class:`BridgeDriver`, :class:`SimServer`) — and its thin names for the
kinematic loop and the MuJoCo simulation."""

from dqcontrol.sim.bridge import BridgeDriver, SimServer
from dqcontrol.sim.driver import (
    JointDriver,
    JointMismatchError,
    KinematicDriver,
    MujocoDriver,
    PositionInterface,
    SimulatedDriver,
    SimulationDriver,
    VelocityFromPosition,
    joint_map,
)
from dqcontrol.sim.kinematic import run_kinematic
from dqcontrol.sim.loop import RunResult, run_loop
from dqcontrol.sim.measurement_faults import FaultyDriver, MeasurementFaults
from dqcontrol.sim.model_faults import (
    DynamicSimulation,
    NotASimulatorError,
    PayloadDriver,
    TorqueLimitDriver,
)
from dqcontrol.sim.mujoco_loop import run_mujoco
from dqcontrol.sim.mujoco_sim import Measurement, MujocoSimulation, ServoGains
from dqcontrol.sim.reflexes import ReflexDriver, ReflexError, Reflexes
from dqcontrol.sim.run_contacts import measure_contacts

__all__ = [
    "BridgeDriver",
    "DynamicSimulation",
    "FaultyDriver",
    "JointDriver",
    "JointMismatchError",
    "KinematicDriver",
    "Measurement",
    "MeasurementFaults",
    "MujocoDriver",
    "MujocoSimulation",
    "NotASimulatorError",
    "PayloadDriver",
    "PositionInterface",
    "ReflexDriver",
    "ReflexError",
    "Reflexes",
    "RunResult",
    "ServoGains",
    "SimServer",
    "SimulatedDriver",
    "SimulationDriver",
    "TorqueLimitDriver",
    "VelocityFromPosition",
    "joint_map",
    "measure_contacts",
    "run_kinematic",
    "run_loop",
    "run_mujoco",
]
