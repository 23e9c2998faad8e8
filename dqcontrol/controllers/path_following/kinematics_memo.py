"""The forward kinematics and target a controller's last step evaluated last, for the
next step at the same configuration or phase.

A step that checks its linearisation evaluates the pose after the applied command and the
target at the next phase; where the next measured configuration is exactly that one (a
simulated loop, a robot at rest) the next step reads them back instead of evaluating them
again. Keys are compared value for value (``0.0`` and ``-0.0`` alike), so what is read
back is what would be computed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.controllers.prediction.distance import max_abs_difference

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.model.robot import RobotModel
    from dqcontrol.trajectories import Trajectory

__all__ = ["KinematicsMemo"]

_NONE = (None, np.zeros(0))


class KinematicsMemo:
    """The pose (by configuration) and the target (by trajectory and phase) kept during one
    step, read during the next (:meth:`advance` between them); each is handed out once,
    so that no two callers share an array."""

    def __init__(self, robot: RobotModel) -> None:
        self._fast = robot.fast
        self._pose_kept: tuple = _NONE  # (q, f(q)) of this step
        self._pose_read: tuple = _NONE  # (q, f(q)) of the last step
        self._target_kept: tuple = (None, 0.0, _NONE[1])  # (trajectory, σ, x_d(σ))
        self._target_read: tuple = (None, 0.0, _NONE[1])

    def clear(self) -> None:
        """Forget everything."""
        self._pose_kept = self._pose_read = _NONE
        self._target_kept = self._target_read = (None, 0.0, _NONE[1])

    def advance(self) -> None:
        """A new step: what this one kept is read next, and nothing is kept yet."""
        self._pose_read, self._pose_kept = self._pose_kept, _NONE
        self._target_read, self._target_kept = self._target_kept, (None, 0.0, _NONE[1])

    def keep_pose(self, q: np.ndarray, pose: np.ndarray) -> None:
        """Keep ``pose = f(q)`` (``q`` and ``pose`` must not change afterwards)."""
        self._pose_kept = (q, pose)

    def pose(self, q: np.ndarray) -> np.ndarray:
        """``f(q)`` (vec8, ``r_w ≥ 0``): the last step's if ``q`` has its values."""
        kept, pose = self._pose_read
        if kept is not None and max_abs_difference(kept, q) == 0.0:
            self._pose_read = _NONE
            return pose
        return self._fast.poses(q[None, :])[0]

    def keep_target(self, trajectory: Trajectory, sigma: float, target: np.ndarray) -> None:
        """Keep ``target = trajectory.target(sigma)``."""
        self._target_kept = (trajectory, sigma, target)

    def target(self, trajectory: Trajectory, sigma: float) -> np.ndarray:
        """``trajectory.target(sigma)``: the last step's for the same trajectory and phase."""
        kept, kept_sigma, target = self._target_read
        if kept is trajectory and kept_sigma == sigma:
            self._target_read = (None, 0.0, _NONE[1])
            return target
        return trajectory.target(sigma)
