"""What the terms and limits of one step read (docs/theory.md §7)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.linalg.lanes import lane_dot

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.prediction.base import Prediction
    from dqcontrol.model.robot import RobotModel
    from dqcontrol.trajectories import Trajectory

__all__ = ["StepContext", "align_into", "aligned_kinematics"]


@dataclass
class StepContext:
    """The measured state, the prediction and the kinematics shared by every term and limit.

    Attributes:
        robot, trajectory: the model and the (anchored) task.
        layout: the decision layout.
        period_s: control period ``T`` [s].
        q: measured joint positions [rad] ``(n,)``.
        qd_prev: the command applied during the last period [rad/s] ``(n,)``.
        sigma: phase ``σ`` now [s of nominal time].
        prediction: the predicted states of each block (:class:`Prediction`).
        poses: ``f(q̄_i)`` (vec8) ``(p, 8)``, sign-aligned to ``targets``.
        jacobians: ``J(q̄_i)`` ``(p, 8, n)``, with the same signs as ``poses``.
        targets: ``x_d(σ̄_i)`` ``(p, 8)``.
        target_derivatives: ``dx_d/dσ(σ̄_i)`` ``(p, 8)``.
        a_max: acceleration bound at each block's linearisation state [rad/s²] ``(p, n)``.
        s_prev: the time scaling applied at the last step (0 before the first).
        lag_s: how far the phase is behind the clock, ``t - σ`` [s] (0: on time).
        posture_scale: the share of the posture gain in force (0 holds the posture term's
            pull off, e.g. while a task is stalled).
        qd_measured: the measured joint velocities [rad/s] ``(n,)``, where the controller
            was given them (``None``: take ``qd_prev``, the command).
        qd_before_prev: the command applied the period before ``qd_prev`` [rad/s] ``(n,)``
            (the jerk of the applied command, docs/theory.md §8.11; ``None``: ``qd_prev``).
    """

    robot: RobotModel
    trajectory: Trajectory
    layout: DecisionLayout
    period_s: float
    q: np.ndarray
    qd_prev: np.ndarray
    sigma: float
    prediction: Prediction
    poses: np.ndarray
    jacobians: np.ndarray
    targets: np.ndarray
    target_derivatives: np.ndarray
    a_max: np.ndarray
    s_prev: float = 0.0
    lag_s: float = 0.0
    posture_scale: float = 1.0
    qd_measured: np.ndarray | None = None
    qd_before_prev: np.ndarray | None = None

    @property
    def qd_now(self) -> np.ndarray:
        """The joint velocities now [rad/s]: measured where given, else the last command."""
        return self.qd_prev if self.qd_measured is None else self.qd_measured


def aligned_kinematics(
    robot: RobotModel, trajectory: Trajectory, q_lin: np.ndarray, sigma_lin: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(poses, jacobians, targets, target_derivatives)`` at the linearisation states, each
    pose (and its Jacobian) negated where ``x · x_d < 0`` (docs/theory.md §1)."""
    xs, jacs = robot.fast.poses_and_jacobians(q_lin)  # fresh arrays: negated in place
    xd, dxd = trajectory.targets(sigma_lin)
    align_into(xs, jacs, xd)
    return xs, jacs, xd, dxd


@compiled
def align_into(poses: np.ndarray, jacobians: np.ndarray, targets: np.ndarray) -> None:
    """Negate ``poses[i]`` and ``jacobians[i]`` in place where ``poses[i] · targets[i] < 0``
    (the product summed as numpy's ``einsum`` sums it, :func:`lane_dot`)."""
    for i in range(poses.shape[0]):
        if lane_dot(poses[i], targets[i]) < 0.0:
            for k in range(poses.shape[1]):
                poses[i, k] = -poses[i, k]
                for j in range(jacobians.shape[2]):
                    jacobians[i, k, j] = -jacobians[i, k, j]
