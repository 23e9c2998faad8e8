"""Closed loops: the kinematic loop (ideal velocity tracking) and the MuJoCo simulation."""

from dqcontrol.sim.kinematic import RunResult, run_kinematic
from dqcontrol.sim.mujoco_loop import run_mujoco
from dqcontrol.sim.mujoco_sim import Measurement, MujocoSimulation, ServoGains

__all__ = [
    "Measurement",
    "MujocoSimulation",
    "RunResult",
    "ServoGains",
    "run_kinematic",
    "run_mujoco",
]
