"""Proportional control on the invariant dual-quaternion error (docs/theory.md §4.1).

Thesis eq. 2.31–2.34: with ``e = 1 - x* x_d`` and ``N = H-8(x_d) C8 J``, imposing
``ė = -K e`` gives ``N qd = K vec8(e) - vec8(x* ẋ_d)``, solved with the damped
pseudo-inverse ``N⁺ = Nᵀ (N Nᵀ + λ² I)⁻¹`` so singular configurations stay bounded.
There is no time scaling (``σ = t``); the command is clipped to the hard bounds of
docs/theory.md §5 (reported as ``saturated``), which keeps the arm safe but may deform the
path — the reason the QP controllers exist.

The step runs at 1 kHz, and on arrays this small each numpy call costs more than its
arithmetic, so it is written for few calls: both Hamilton matrices from the target pair in
one product, the box in one compiled call (:func:`_clip_to_box`: the joint box and the
acceleration bound with its conflict rule, the kernels of the QP controllers' limits,
``joint_box.near_limit_box`` and ``intersect_hard``), the results built without per-field
``__setattr__``. ``tests/controllers/test_proportional.py`` checks it against the plain
computation.
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
    fast_constructor,
    per_joint,
    robot_acceleration_limit,
)
from dqcontrol.controllers.core.bounds import braking_constants, command_box
from dqcontrol.controllers.core.box_rules import joint_boxes, joint_constants, project
from dqcontrol.controllers.limits.jerk import applied_jerk_box, jerk_setting
from dqcontrol.controllers.limits.servo_lag import ServoLagMargin
from dqcontrol.dq.algebra import _HM8, C8
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = ["ProportionalController"]

_ONE = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])
_C8_DIAG = np.diagonal(C8).copy()
#: ``H-8(y) C8`` is linear in ``y``: ``(H-8(y) C8).ravel() = _HM8_C8 @ y``
_HM8_C8 = (_HM8.reshape(8, 8, 8) * _C8_DIAG[None, :, None]).reshape(64, 8)


def _target_map(gain_per_s: float) -> np.ndarray:
    """``(16, 128)`` constant ``M`` with ``[x_d, dx_d] @ M = [H-8(x_d) C8, H-8(K x_d + dx_d) C8]``
    (both flattened): the two matrices the step needs, from the target pair in one product.

    With them ``x* x_d = H-8(x_d) C8 x`` and ``N = H-8(x_d) C8 J``, and the right-hand side
    ``K vec8(1 - x* x_d) - vec8(x* dx_d) = K·1 - H-8(K x_d + dx_d) C8 x`` (bilinearity).
    """
    out = np.zeros((16, 128))
    out[:8, :64] = _HM8_C8.T
    out[:8, 64:] = gain_per_s * _HM8_C8.T  # entries 0, ±1: exact
    out[8:, 64:] = _HM8_C8.T
    return out


def _solve_spd(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``gram⁻¹ rhs`` for the damped Gram matrix (symmetric positive definite when the
    damping is > 0): LAPACK's Cholesky solve (``dposv``, upper triangle; positional
    arguments, which the f2py wrapper parses faster than keywords); an LU solve where
    Cholesky fails (no damping at a singularity; ``dposv`` leaves its inputs unchanged)."""
    _, sol, info = _POSV(gram, rhs)
    if info == 0:
        return sol
    return np.linalg.solve(gram, rhs)


def _clip_to_box(
    qd: np.ndarray,
    q: np.ndarray,
    qd_prev: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    qd_max: np.ndarray,
    a_max: np.ndarray,
    period_s: float,
    consts: np.ndarray,
    braking: bool,
    jerk_box: np.ndarray | None = None,
) -> tuple[np.ndarray, bool, tuple[int, ...]]:
    """``command_box(...).project(qd)``, whether it clipped, and the conflict joints.

    ``jerk_box`` ``(2, n)`` (the jerk limit's interval of each joint's command, or ``None``)
    is intersected with the box where they meet; where they do not, the box holds (a
    position or velocity bound before the jerk).

    The box by the compiled :func:`~dqcontrol.controllers.core.box_rules.joint_boxes` (the
    floating-point operations of ``bounds.command_box``), ``consts`` from
    :func:`~dqcontrol.controllers.core.box_rules.joint_constants` as an ``(n, 6)`` array; where
    that kernel declines (a NaN previous command or limit, a bound beyond ±1e30: what a QP
    could not take), ``command_box`` itself. Returns ``qd`` itself (not a copy) when
    nothing is clipped.
    """
    n = qd.shape[0]
    bounds = np.empty((2, n))
    flags = np.empty(n, dtype=np.int8)
    if joint_boxes(q, qd_prev, q_min, q_max, consts, period_s, braking, bounds, flags) < 0:
        box = command_box(q, qd_prev, q_min, q_max, qd_max, a_max, period_s, braking)
        out = box.project(qd)
        saturated = not np.array_equal(out, qd)
        flags = box.conflict
    else:
        if jerk_box is not None:
            lo, hi = np.maximum(bounds[0], jerk_box[0]), np.minimum(bounds[1], jerk_box[1])
            meet = lo <= hi
            bounds[0], bounds[1] = np.where(meet, lo, bounds[0]), np.where(meet, hi, bounds[1])
        out = np.empty(n)
        saturated = project(qd, bounds, out)
    conflict = tuple(np.flatnonzero(flags).tolist()) if flags.any() else ()
    return (out if saturated else qd), saturated, conflict


class ProportionalController(Controller):
    """Invariant-error proportional controller.

    Args:
        robot, trajectory, period_s: see :class:`~dqcontrol.controllers.base.Controller`.
        gain_per_s: ``K`` [1/s]; keep ``T K`` well below 2 (docs/theory.md §4.3).
        damping: ``λ`` of the damped pseudo-inverse (dimensionless, ≥ 0).
        velocity_limits: ``qd_max`` [rad/s] (default: the URDF's).
        acceleration_limit: ``a_max`` [rad/s²] for the clipping box; ``None`` (default): the
            robot's limit profile's acceleration limit, else 10 rad/s².
        braking_aware: add the stop-before-the-limit position bound (bounds.py).
        position_margin_rad: the position bounds stop this far inside the URDF's limits
            [rad] (default 5 mrad, see
            :class:`~dqcontrol.controllers.thesis.controller.TrackingController`).
        measurement_delay_periods: see :class:`~dqcontrol.controllers.base.Controller`.
        saturate: clip the command to the hard bounds (default True).
        jerk_limit: joint jerk bound of the commands [rad/s³] (docs/theory.md §8.11: the
            applied jerk, and the velocity and braking bounds that keep it feasible, in the
            box); ``None`` (default): the robot's limit profile's, none when it gives none.
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
        acceleration_limit: float | np.ndarray | None = None,
        braking_aware: bool = True,
        position_margin_rad: float = 5e-3,
        measurement_delay_periods: int = 0,
        saturate: bool = True,
        jerk_limit: float | np.ndarray | None = None,
    ) -> None:
        super().__init__(robot, trajectory, period_s, measurement_delay_periods)
        self.gain_per_s = check_positive("gain_per_s (K)", gain_per_s, "1/s")
        self.damping = check_positive("damping (lambda)", damping, "-", allow_zero=True)
        lim = robot.limits
        qd_max = lim.qd_max if velocity_limits is None else velocity_limits
        self.qd_max = per_joint("velocity_limits", qd_max, self.n, "rad/s")
        a_max = robot_acceleration_limit(robot, acceleration_limit, 10.0)
        self.a_max = per_joint("acceleration_limit", a_max, self.n, "rad/s²")
        margin = check_position_margin(position_margin_rad, lim.q_min, lim.q_max)
        self.position_margin_rad = margin
        self.q_min, self.q_max = lim.q_min + margin, lim.q_max - margin
        # the servo's measured lag moves the position bounds of the box (docs/theory.md §5)
        self._lag = ServoLagMargin(lim.q_min, lim.q_max, margin, self.period_s, self.a_max)
        self._lag_bounds = np.empty((2, self.n))
        self.jerk = jerk_setting(robot, jerk_limit)
        self.qd_before_prev = np.zeros(self.n)  # u_2, the command before the last
        self.braking_aware = bool(braking_aware)
        self.saturate = bool(saturate)
        self._damping_eye = self.damping**2 * np.eye(8)
        self._jacobian = np.empty((8, self.n))  # filled at each step
        # the box: a_max and braking_aware are taken at construction (as before); q_min,
        # q_max, qd_max and T are read at every step, and the constants that depend on
        # qd_max and T rebuilt when they change
        at, two_a, at2 = braking_constants(self.a_max, self.period_s)
        step = self.period_s * self.a_max  # the acceleration bound's half-width
        self._box_limits = list(
            zip(at.tolist(), two_a.tolist(), at2.tolist(), step.tolist(), strict=True)
        )
        self._braking = self.braking_aware
        self._box_key: tuple = ()
        self._box_consts = np.zeros((0, 6))
        self._map_gain = self.gain_per_s
        self._map = _target_map(self.gain_per_s)
        self._gain_one = self.gain_per_s * _ONE
        zero = np.zeros(self.n)
        self._new_diag = fast_constructor(StepDiagnostics, status="closed_form")
        self._new_result = fast_constructor(
            StepResult, qd_command=zero, s=1.0, sigma=0.0, sigma_next=0.0, pose=_ONE,
            target=_ONE, diagnostics=StepDiagnostics(status="closed_form"),
        )  # fmt: skip

    def _position_bounds(self, qd: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """The box's position bounds [rad]: ``q_min``, ``q_max`` moved inwards by the
        servo's measured lag where its travel exceeds the margin
        (:class:`~dqcontrol.controllers.limits.servo_lag.ServoLagMargin`; not with a
        compensated measurement delay, whose measured velocity is older than the command)."""
        bounds = self._lag_bounds
        bounds[0], bounds[1] = self.q_min, self.q_max
        measured = None if self.measurement_delay_periods else qd
        self._lag.update(measured, self.qd_prev, bounds)
        return bounds[0], bounds[1]

    def _reset_memory(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        self._lag.reset()
        self.qd_before_prev = qd0.copy()
        super()._reset_memory(q0, qd0)

    def _jerk_box(self, q: np.ndarray, q_min: np.ndarray, q_max: np.ndarray) -> np.ndarray | None:
        """The jerk limit's interval of each joint's command ``(2, n)`` [rad/s]: the applied
        jerk's (hard) and the velocity and braking bounds that keep the next step feasible
        (soft); where they do not meet, the point of the hard interval nearest the soft one
        (as a QP that relaxes the soft bounds would choose); ``None`` without a jerk limit."""
        if self.jerk is None:
            return None
        box = np.empty((4, self.n))
        applied_jerk_box(
            q, self.qd_prev, self.qd_before_prev, self.a_max, self.jerk, self.qd_max,
            q_min, q_max, self.period_s, box,
        )  # fmt: skip
        lo, hi = np.maximum(box[0], box[2]), np.minimum(box[1], box[3])
        nearest = np.where(box[0] > box[3], box[3], box[2])
        meet = lo <= hi
        return np.array([np.where(meet, lo, nearest), np.where(meet, hi, nearest)])

    def _step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        start = time.perf_counter()
        x, jac = np.empty(8), self._jacobian  # the pose is the result's: a new array a step
        self.robot._pose_and_jacobian_into(q, x, jac)
        sigma = self.sigma
        pair = self.trajectory.target_pair(sigma)  # [x_d; dx_d/dσ], s = 1: d/dt = d/dσ
        xd = pair[0]
        if x.dot(xd) < 0.0:
            x, jac = -x, -jac
        if self.gain_per_s != self._map_gain:  # K changed since the map was built
            self._map_gain = self.gain_per_s
            self._map = _target_map(self.gain_per_s)
            self._gain_one = self.gain_per_s * _ONE
        # [H-8(x_d) C8, H-8(K x_d + dx_d) C8] in one product (see _target_map)
        hm = pair.reshape(16).dot(self._map).reshape(2, 8, 8)
        n_mat = hm[0].dot(jac)  # N = H-8(x_d) C8 J
        rhs = self._gain_one - hm[1].dot(x)  # K vec8(e) - vec8(x* dx_d)
        gram = n_mat.dot(n_mat.T)
        gram += self._damping_eye
        qd_cmd = _solve_spd(gram, rhs).dot(n_mat)  # Nᵀ (N Nᵀ + λ² I)⁻¹ rhs
        saturated = False
        conflict: tuple[int, ...] = ()
        message = ""
        # a sum is NaN/inf iff some entry is (or it overflows): cheap first test
        if not (math.isfinite(qd_cmd.sum()) or np.isfinite(qd_cmd).all()):
            qd_cmd = np.zeros(self.n)
            message = "non-finite command replaced by zero"
        if self.saturate:
            key = (self.period_s, self.qd_max.tolist())
            if key != self._box_key:
                self._box_key = key
                self._box_consts = np.array(
                    joint_constants(self._box_limits, key[1], self.period_s, self._braking)
                )
            q_min, q_max = self._position_bounds(qd)
            qd_cmd, saturated, conflict = _clip_to_box(
                qd_cmd, q, self.qd_prev, q_min, q_max, self.qd_max, self.a_max,
                self.period_s, self._box_consts, self._braking, self._jerk_box(q, q_min, q_max),
            )  # fmt: skip
        self.qd_before_prev = self.qd_prev
        diag = self._new_diag(
            status="closed_form",
            step_time_s=time.perf_counter() - start,
            saturated=saturated,
            conflict_joints=conflict,
            message=message,
        )
        return self._new_result(
            qd_command=qd_cmd,
            s=1.0,
            sigma=sigma,
            sigma_next=sigma + self.period_s,
            pose=x,
            target=xd,
            diagnostics=diag,
        )
