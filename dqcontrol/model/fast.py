"""The robot model's unchecked API for the control loop's hot path.

The checked methods of :class:`~dqcontrol.model.robot.RobotModel` validate every joint
vector (shape, NaN/inf) and return fresh copies; a controller that has already checked its
inputs calls these instead. Each returns fresh arrays the caller may modify (the ``_into``
methods write into the caller's instead).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.model.robot import RobotModel

__all__ = ["UncheckedModel"]


class UncheckedModel:
    """``robot.fast``: kinematics and dynamics without input checks (inputs must be valid
    ``float64`` arrays of the right shape)."""

    def __init__(self, robot: RobotModel) -> None:
        self._robot = robot

    def pose_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pose ``vec8`` (8,) and pose Jacobian (8, n) at ``q``."""
        return self._robot._pose_and_jacobian(q)

    def pose_and_jacobian_into(self, q: np.ndarray, x: np.ndarray, jac: np.ndarray) -> None:
        """:meth:`pose_and_jacobian` written into ``x`` (8,) and ``jac`` (8, n): no arrays
        made (each a compiled function returns costs the 1 kHz step about 0.4 µs)."""
        self._robot._pose_and_jacobian_into(q, x, jac)

    def pose(self, q: np.ndarray) -> np.ndarray:
        """Pose ``vec8`` (8,) at ``q`` (the kinematics alone)."""
        return self._robot._pose(q)

    def poses(self, qs: np.ndarray) -> np.ndarray:
        """Batched poses ``(N, 8)`` without the Jacobians (``r_w ≥ 0``): in closed form
        where the model's chain has one (:mod:`~dqcontrol.model.chain_batch`), else from
        Pinocchio one by one. They agree with :meth:`poses_and_jacobians`' poses to
        rounding, not bit for bit."""
        chain = self._robot._chain
        if chain is not None:
            return chain.poses(qs)
        robot = self._robot
        return np.array([robot._pose(q) for q in qs]).reshape(qs.shape[0], 8)

    def poses_and_jacobians(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Batched poses ``(N, 8)`` and Jacobians ``(N, 8, n)``."""
        return self._robot._poses_and_jacobians(qs)

    def acceleration_limits(
        self, q: np.ndarray, effort_fraction: float, floor: float, cap: float
    ) -> np.ndarray:
        """``clip((f τ_max - |g(q)|) / M_jj(q), floor, cap)`` [rad/s²] (docs/theory.md §5)."""
        return self._robot._acceleration_limits(q, effort_fraction, floor, cap)

    def acceleration_limits_batch(
        self, qs: np.ndarray, effort_fraction: float, floor: float, cap: float
    ) -> np.ndarray:
        """:meth:`acceleration_limits` at each row of ``qs`` ``(N, n)``."""
        return self._robot._acceleration_limits_batch(qs, effort_fraction, floor, cap)

    def mass_gravity(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(M(q) (n, n), g(q) (n,))`` [kg·m², N·m]."""
        robot = self._robot
        m = pin.crba(robot.model, robot.data, q)
        m = np.triu(m) + np.triu(m, 1).T
        g = np.array(pin.computeGeneralizedGravity(robot.model, robot.data, q))
        return m, g

    def bias_forces(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """``C(q, qd) qd + g(q)`` [N·m] (Pinocchio's non-linear effects)."""
        robot = self._robot
        return np.array(pin.nonLinearEffects(robot.model, robot.data, q, qd))
