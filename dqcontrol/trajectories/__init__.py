"""Trajectories: geometric pose paths ``traj(σ)`` in a reference frame (docs/theory.md §3).

Every trajectory implements the :class:`Trajectory` contract: ``target(σ) = ref ⊗ traj(σ)``
and its derivative with respect to the phase ``σ`` [s of nominal time], batched for the
predictive controller, anchoring at the robot's start pose, and path deviation [m].

- :class:`Circle` — the thesis's circle (eq. 5.1);
- :class:`Sinusoid` — the thesis's sinusoid (eq. 5.3);
- :class:`WaypointTrajectory` — a C² spline through position/orientation waypoints;
- :class:`FunctionTrajectory` — any path given as plain Python functions.

The first three describe themselves (:meth:`Trajectory.to_metadata`) and are rebuilt from
that description by :func:`trajectory_from_metadata`.
"""

from dqcontrol.trajectories.base import Trajectory
from dqcontrol.trajectories.circle import Circle
from dqcontrol.trajectories.functional import FunctionTrajectory
from dqcontrol.trajectories.metadata import TRAJECTORY_KINDS, trajectory_from_metadata
from dqcontrol.trajectories.sinusoid import Sinusoid
from dqcontrol.trajectories.waypoints import WaypointTrajectory

__all__ = [
    "TRAJECTORY_KINDS",
    "Circle",
    "FunctionTrajectory",
    "Sinusoid",
    "Trajectory",
    "WaypointTrajectory",
    "trajectory_from_metadata",
]
