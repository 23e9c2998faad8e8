"""Closed loops: the kinematic loop (ideal velocity tracking) and the MuJoCo simulation."""

from dqcontrol.sim.kinematic import RunResult, run_kinematic

__all__ = ["RunResult", "run_kinematic"]
