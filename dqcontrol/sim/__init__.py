"""Closed loops: one control loop (:func:`run_loop`) against a joint driver — ideal kinematic,
MuJoCo, a position-only interface or a faulty wrapper — and its thin names for the kinematic
loop and the MuJoCo simulation."""

from dqcontrol.sim.driver import (
    FaultyDriver,
    JointDriver,
    JointMismatchError,
    KinematicDriver,
    MeasurementFaults,
    MujocoDriver,
    PositionInterface,
    SimulatedDriver,
    SimulationDriver,
    VelocityFromPosition,
    joint_map,
)
from dqcontrol.sim.kinematic import run_kinematic
from dqcontrol.sim.loop import RunResult, run_loop
from dqcontrol.sim.mujoco_loop import run_mujoco
from dqcontrol.sim.mujoco_sim import Measurement, MujocoSimulation, ServoGains

__all__ = [
    "FaultyDriver",
    "JointDriver",
    "JointMismatchError",
    "KinematicDriver",
    "Measurement",
    "MeasurementFaults",
    "MujocoDriver",
    "MujocoSimulation",
    "PositionInterface",
    "RunResult",
    "ServoGains",
    "SimulatedDriver",
    "SimulationDriver",
    "VelocityFromPosition",
    "joint_map",
    "run_kinematic",
    "run_loop",
    "run_mujoco",
]
