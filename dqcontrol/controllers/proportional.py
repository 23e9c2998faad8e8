"""Proportional control on the invariant dual-quaternion error (FORMULATION §5.1).

Thesis eq. 2.31–2.34: with ``e = 1 - x* x_d`` and ``N = H-8(x_d) C8 J``, imposing
``ė = -K e`` gives ``N qd = K vec8(e) - vec8(x* ẋ_d)``, solved with the damped
pseudo-inverse ``N⁺ = Nᵀ (N Nᵀ + λ² I)⁻¹`` so singular configurations stay bounded.
There is no time scaling (``σ = t``); the command is clipped to the hard bounds of §6
(reported as ``saturated``), which keeps the arm safe but may deform the path — the
reason the QP controllers exist.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.linalg.lapack import dposv as _POSV

from dqcontrol.controllers.base import (
    Controller,
    StepDiagnostics,
    StepResult,
    check_position_margin,
    check_positive,
    per_joint,
)
from dqcontrol.controllers.bounds import _vp_box, braking_constants, intersect_acceleration
from dqcontrol.dq.algebra import C8, haminus8, hamiplus8
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = ["ProportionalController"]

_ONE = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])
_C8_DIAG = np.diagonal(C8).copy()
_DIAG8 = np.arange(8)


def _solve_spd(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``gram⁻¹ rhs`` for the damped Gram matrix (symmetric positive definite when the
    damping is > 0): LAPACK's Cholesky solve, a third of ``np.linalg.solve``'s overhead;
    an LU solve where Cholesky fails (no damping at a singularity)."""
    _, sol, info = _POSV(gram, rhs, lower=False)
    if info == 0:
        return sol
    return np.linalg.solve(gram, rhs)


class ProportionalController(Controller):
    """Invariant-error proportional controller.

    Args:
        robot, trajectory, period_s: see :class:`~dqcontrol.controllers.base.Controller`.
        gain_per_s: ``K`` [1/s]; keep ``T K`` well below 2 (FORMULATION §9).
        damping: ``λ`` of the damped pseudo-inverse (dimensionless, ≥ 0).
        velocity_limits: ``qd_max`` [rad/s] (default: the URDF's).
        acceleration_limit: ``a_max`` [rad/s²] for the clipping box.
        braking_aware: add the stop-before-the-limit position bound (bounds.py).
        position_margin_rad: the position bounds stop this far inside the URDF's limits
            [rad] (default 5 mrad, see TrackingController).
        measurement_delay_periods: see :class:`~dqcontrol.controllers.base.Controller`.
        saturate: clip the command to the hard bounds (default True).
    """

    name = "proportional"

    def __init__(
        self,
        robot: RobotModel,
        trajectory: Trajectory,
        period_s: float,
        *,
        gain_per_s: float = 10.0,
        damping: float = 1e-3,
        velocity_limits: float | np.ndarray | None = None,
        acceleration_limit: float | np.ndarray = 10.0,
        braking_aware: bool = True,
        position_margin_rad: float = 5e-3,
        measurement_delay_periods: int = 0,
        saturate: bool = True,
    ) -> None:
        super().__init__(robot, trajectory, period_s, measurement_delay_periods)
        self.gain_per_s = check_positive("gain_per_s (K)", gain_per_s, "1/s")
        self.damping = check_positive("damping (lambda)", damping, "-", allow_zero=True)
        lim = robot.limits
        qd_max = lim.qd_max if velocity_limits is None else velocity_limits
        self.qd_max = per_joint("velocity_limits", qd_max, self.n, "rad/s")
        self.a_max = per_joint("acceleration_limit", acceleration_limit, self.n, "rad/s²")
        margin = check_position_margin(position_margin_rad, lim.q_min, lim.q_max)
        self.position_margin_rad = margin
        self.q_min, self.q_max = lim.q_min + margin, lim.q_max - margin
        self.braking_aware = bool(braking_aware)
        self.saturate = bool(saturate)
        self._damping_eye = self.damping**2 * np.eye(8)
        self._brake = braking_constants(self.a_max, self.period_s) if braking_aware else None
        self._accel_step = self.period_s * self.a_max

    def _step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        start = time.perf_counter()
        x, jac = self.robot._pose_and_jacobian(q)
        sigma = self.sigma
        pair = self.trajectory.target_pair(sigma)  # [x_d; dx_d/dσ], s = 1: d/dt = d/dσ
        xd = pair[0]
        if x.dot(xd) < 0.0:
            x, jac = -x, -jac
        # x* x_d and x* dx_d with one Hamilton matrix: H+8(x*) [x_d, dx_d]
        prods = hamiplus8(_C8_DIAG * x).dot(pair.T)
        err = _ONE - prods[:, 0]
        n_mat = (haminus8(xd) * _C8_DIAG).dot(jac)  # H-8(x_d) C8 J
        rhs = self.gain_per_s * err - prods[:, 1]
        gram = n_mat.dot(n_mat.T)
        gram += self._damping_eye
        qd_cmd = n_mat.T.dot(_solve_spd(gram, rhs))
        saturated = False
        conflict: tuple[int, ...] = ()
        message = ""
        if not (math.isfinite(qd_cmd.dot(qd_cmd)) or np.isfinite(qd_cmd).all()):
            qd_cmd = np.zeros(self.n)
            message = "non-finite command replaced by zero"
        if self.saturate:
            lo_vp, hi_vp = _vp_box(
                q, self.q_min, self.q_max, self.qd_max, self.period_s, self._brake
            )  # command_box() with the constants precomputed
            box = intersect_acceleration(lo_vp, hi_vp, self.qd_prev, self._accel_step)
            clipped = box.project(qd_cmd)
            saturated = not np.array_equal(clipped, qd_cmd)
            qd_cmd = clipped
            if box.conflict.any():
                conflict = tuple(np.flatnonzero(box.conflict).tolist())
        diag = StepDiagnostics(
            status="closed_form",
            step_time_s=time.perf_counter() - start,
            saturated=saturated,
            conflict_joints=conflict,
            message=message,
        )
        return StepResult(
            qd_command=qd_cmd,
            s=1.0,
            sigma=sigma,
            sigma_next=sigma + self.period_s,
            pose=x,
            target=xd,
            diagnostics=diag,
        )
