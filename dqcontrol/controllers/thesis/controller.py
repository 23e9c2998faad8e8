"""The thesis's QP controllers with time scaling, composed on the QP core (docs/theory.md
§4.2, §7.6): local (one block) and predictive (p blocks at the instants ``τ_i``).

At the instants ``τ_1 = 0 < τ_2 < … < τ_p``, with ``z_i = [qd_i; s_i]``:

    minimize   Σ_i λ1 ‖J_i qd_i - s_i w_i‖² + λ2 (1 - s_i)² + μ ‖qd_i‖²  (+ stall damping)
    subject to qd_1 in the command box at q (velocity, position, braking, acceleration),
               qd_i in the velocity/position box at q̂_i             (i ≥ 2),
               |qd_i - qd_{i-1}| ≤ (τ_i - τ_{i-1}) a_max(q̂_i)        (i ≥ 2),
               0 ≤ s_i ≤ 1   (s_i ≡ 1 without scaling)

with ``w_i = dx_d/dσ(σ̂_i) + K (x_d(σ̂_i) - x̂_i)``. As a composition:

- prediction: :class:`~dqcontrol.controllers.prediction.thesis.ThesisPrediction`;
- terms: :class:`~dqcontrol.controllers.terms.tracking.TrackingTerm` (``λ1``),
  :class:`~dqcontrol.controllers.terms.scaling.ScalingTerm` (``λ2``),
  :class:`~dqcontrol.controllers.terms.damping.DampingTerm` (``μ``),
  :class:`~dqcontrol.controllers.terms.stall_damping.StallDampingTerm`;
- limits: :class:`~dqcontrol.controllers.limits.command_box.CommandBoxLimit` (the applied
  block's :class:`~dqcontrol.controllers.limits.joint_box.JointBoxLimit` and the hard
  :class:`~dqcontrol.controllers.limits.acceleration.AccelerationLimit` with the coupling
  rows, in one pass), the predicted blocks' joint boxes (relaxable),
  :class:`~dqcontrol.controllers.limits.scaling_range.ScalingRange`;
- levels: ``priority="weighted"`` (the thesis: one level, the weights above) or
  ``"strict"`` (three levels: tracking ≻ scaling ≻ damping, docs/theory.md §7.6).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from dqcontrol.controllers.backends.base import DEFAULT_SOLVER, check_backend_name
from dqcontrol.controllers.base import (
    StepResult,
    acceleration_setting,
    check_positive,
    joint_limit_settings,
    robot_acceleration_limit,
)
from dqcontrol.controllers.core.problem import DecisionLayout, DenseQP, Level
from dqcontrol.controllers.limits.acceleration import AccelerationLimit
from dqcontrol.controllers.limits.command_box import CommandBoxLimit
from dqcontrol.controllers.limits.jerk import jerk_limits, jerk_setting
from dqcontrol.controllers.limits.joint_box import JointBoxLimit
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.limits.scaling_range import ScalingRange
from dqcontrol.controllers.limits.servo_lag import ServoLagMargin
from dqcontrol.controllers.prediction.thesis import ThesisPrediction
from dqcontrol.controllers.qp_controller import QPController
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.controllers.terms.scaling import ScalingTerm
from dqcontrol.controllers.terms.stall_damping import StallDampingTerm
from dqcontrol.controllers.terms.term import Term
from dqcontrol.controllers.terms.tracking import TrackingTerm
from dqcontrol.errors import ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = [
    "DEFAULT_SOLVER",
    "AccelerationSetting",
    "QPProblem",
    "TrackingController",
]

#: A QP ``minimize ½ zᵀ P z + cᵀ z  s.t.  lower ≤ A z ≤ upper`` as dense arrays.
QPProblem = DenseQP

#: ``float`` (constant [rad/s²], or one per joint) or ``"dynamics"`` (docs/theory.md §2).
AccelerationSetting = float | np.ndarray | Literal["dynamics"]

#: How far lower levels may move each held row of a higher level (``priority="strict"``).
STRICT_TOLERANCE = 1e-7


def _instants(instants_s) -> np.ndarray:
    tau = np.asarray(instants_s, dtype=float)
    if tau.ndim != 1 or tau.size < 1 or tau[0] != 0.0 or np.any(np.diff(tau) <= 0.0):
        raise ParameterError(
            f"instants_s must start at 0 and increase strictly [s], got {instants_s!r}"
        )
    return tau


def _forward(attribute: str, doc: str) -> property:
    """A property stored on every joint-box limit of the controller."""

    def get(self):
        return getattr(self._joint_boxes[0], attribute)

    def set_(self, value):
        for limit in self._joint_boxes:
            setattr(limit, attribute, value)

    return property(get, set_, doc=doc)


class TrackingController(QPController):
    """The local and predictive QP controllers of the thesis (module docstring).

    Args:
        robot, trajectory, period_s: see :class:`~dqcontrol.controllers.base.Controller`.
        instants_s: prediction instants ``τ_i`` [s], starting at 0 (``[0]`` = local method).
        gain_per_s: task-error gain ``K`` [1/s]; keep ``T s K`` well below 2
            (docs/theory.md §4.3).
        task_weight: ``λ1`` (dimensionless, > 0).
        scaling_weight: ``λ2`` (≥ 0); ``λ2 ≪ λ1`` puts the task before the speed.
        regularization: ``μ`` [same unit as λ1], the small damping on ``‖qd‖²``.
        stall_damping: ``μ_stall`` (default 1e-3; 0 gives the thesis's cost exactly): once
            the applied ``s`` has stayed below ``stall_scaling`` for ``stall_delay_s``,
            every block's cost gets ``μ_stall (1 - s/stall_scaling) ‖qd‖²`` and the arm
            comes to rest near an unreachable path (docs/theory.md §4.3).
        stall_scaling: the ``s`` below which the task counts as stalled (in ``(0, 1]``).
        stall_delay_s: how long ``s`` must stay below ``stall_scaling`` before the damping
            acts [s] (≥ 0).
        velocity_limits: ``qd_max`` [rad/s], scalar or per joint; default: the URDF's.
        acceleration_limit: constant ``a_max`` [rad/s²] (scalar or per joint) or
            ``"dynamics"`` for Pinocchio's ``(τ_max - |g|)/M_jj`` at each block's state,
            clipped to ``[acceleration_floor, acceleration_cap]``; ``None`` (default): the
            robot's limit profile's acceleration limit, else 10 rad/s²
            (:func:`~dqcontrol.controllers.base.robot_acceleration_limit`).
        jerk_limit: jerk bound of the applied command [rad/s³] (scalar or per joint);
            default: the robot's ``limits.qddd_max`` (no bound where it is infinite;
            docs/theory.md §8.11).
        braking_aware: add the stop-before-the-limit position bound (docs/theory.md §5).
        position_margin_rad: the position bounds stop this far inside the URDF's limits
            [rad] (default 5 mrad: a velocity servo lags its command, so a joint braked to
            its limit overshoots; with encoder noise use ≥ 3σ).
        measurement_delay_periods: see :class:`~dqcontrol.controllers.base.Controller`.
        scaling: optimise ``s`` (True) or hold ``s ≡ 1`` (the method without scaling).
        phase_prediction: ``"previous"`` integrates the previous ``s`` profile to predict
            ``σ̂_i``; ``"nominal"`` uses ``σ + τ_i`` (the thesis).
        solver: ``"daqp"`` (default, docs/theory.md §6) or ``"osqp"`` (ADMM refined to the
            exact optimum); ``solver_settings`` override the solver's own (settings never
            choose the backend: DAQP refuses OSQP's, naming the settings it knows).
        priority: ``"weighted"`` (one level, the thesis) or ``"strict"`` (tracking ≻
            scaling ≻ damping as three levels; needs ``regularization > 0`` and
            ``scaling_weight > 0``).
        extra_terms: more terms, added to the lowest level.
        extra_limits: more limits (any :class:`~dqcontrol.controllers.limits.limit.Limit`).

    ``q_min``, ``q_max``, ``qd_max``, ``braking_aware``, ``gain_per_s`` and ``task_weight``
    are read at every step; the constant terms (``scaling_weight``, ``regularization``)
    are evaluated once.
    """

    name = "tracking"

    q_min = _forward("q_min", "Position bounds [rad] (the URDF's, shrunk by the margin).")
    q_max = _forward("q_max", "Position bounds [rad] (the URDF's, shrunk by the margin).")
    qd_max = _forward("qd_max", "Velocity bound [rad/s] per joint.")
    braking_aware = _forward("braking_aware", "Whether the braking bound is added.")

    def __init__(
        self,
        robot: RobotModel,
        trajectory: Trajectory,
        period_s: float,
        *,
        instants_s: np.ndarray,
        gain_per_s: float = 10.0,
        task_weight: float = 1.0,
        scaling_weight: float = 1e-3,
        regularization: float = 1e-6,
        stall_damping: float = 1e-3,
        stall_scaling: float = 0.05,
        stall_delay_s: float = 0.5,
        velocity_limits: float | np.ndarray | None = None,
        acceleration_limit: AccelerationSetting | None = None,
        acceleration_floor: float = 0.5,
        acceleration_cap: float = 50.0,
        jerk_limit: float | np.ndarray | None = None,
        braking_aware: bool = True,
        position_margin_rad: float = 5e-3,
        measurement_delay_periods: int = 0,
        scaling: bool = True,
        phase_prediction: Literal["previous", "nominal"] = "previous",
        solver: str | None = None,
        solver_settings: dict | None = None,
        priority: Literal["weighted", "strict"] = "weighted",
        extra_terms: tuple[Term, ...] = (),
        extra_limits: tuple[Limit, ...] = (),
    ) -> None:
        super().__init__(
            robot, trajectory, period_s, measurement_delay_periods=measurement_delay_periods
        )
        period_s = self.period_s
        backend = check_backend_name(solver)
        self._check_weights(gain_per_s, task_weight, scaling_weight, regularization)
        self._check_stall(stall_damping, stall_scaling, stall_delay_s)
        self._check_choices(phase_prediction, priority)
        self.scaling = bool(scaling)
        self.instants_s = _instants(instants_s)
        self.p = self.instants_s.size
        acceleration_limit = robot_acceleration_limit(robot, acceleration_limit, 10.0)
        self._set_acceleration(robot.nq, acceleration_limit, acceleration_floor, acceleration_cap)
        layout = self._layout(robot.nq, period_s)
        jerk = self._joint_limits(
            layout, velocity_limits, position_margin_rad, braking_aware, jerk_limit
        )
        prediction = ThesisPrediction(
            layout, period_s, phase_prediction if self.scaling else "nominal"
        )
        levels = self._compose_levels(layout, period_s, tuple(extra_terms))
        limits = self._compose_limits(layout, period_s) + jerk + tuple(extra_limits)
        if self.a_const is not None:
            self._a_batch = np.tile(self.a_const, (self.p, 1))
        self.compose(prediction, levels, limits, backend, solver_settings)

    def _joint_limits(
        self, layout, velocity_limits, position_margin_rad, braking_aware, jerk_limit
    ) -> tuple[Limit, ...]:
        """The joint boxes of the applied command and of the predicted states (one set of
        bounds), the servo-lag margin kept with them, and the jerk limit (returned)."""
        robot, period_s = self.robot, self.period_s
        margin, q_min, q_max, qd_max = joint_limit_settings(
            robot, velocity_limits, position_margin_rad
        )
        self.position_margin_rad = margin
        applied = JointBoxLimit(layout, q_min, q_max, qd_max, braking_aware)
        predicted = JointBoxLimit(layout, q_min, q_max, qd_max, braking_aware, predicted=True)
        predicted.values = applied.values  # one set of bounds (in-place edits included)
        self._joint_boxes = (applied, predicted)
        self._servo_lag = ServoLagMargin(
            robot.limits.q_min, robot.limits.q_max, margin, period_s, self.a_const
        )
        jerk = jerk_setting(robot, jerk_limit)
        return jerk_limits(jerk, layout, period_s, qd_max, q_min, q_max)

    # ------------------------------------------------------------------ servo lag
    def _step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        """The step, the position bounds first moved by the servo's measured lag
        (:class:`~dqcontrol.controllers.limits.servo_lag.ServoLagMargin`; not with a
        compensated measurement delay, whose measured velocity is older than the command)."""
        measured = None if self.measurement_delay_periods else qd
        self._servo_lag.update(measured, self.qd_prev, self._joint_boxes[0].values)
        return super()._step(q, qd)

    def _reset_memory(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        self._servo_lag.restore(self._joint_boxes[0].values)
        super()._reset_memory(q0, qd0)

    # ------------------------------------------------------------------ settings
    def _check_choices(self, phase_prediction: str, priority: str) -> None:
        if phase_prediction not in ("previous", "nominal"):
            raise ParameterError(
                f"phase_prediction must be 'previous' or 'nominal', got {phase_prediction!r}"
            )
        if priority not in ("weighted", "strict"):
            raise ParameterError(f"priority must be 'weighted' or 'strict', got {priority!r}")
        self.phase_prediction, self.priority = phase_prediction, priority

    def _check_weights(self, gain_per_s, task_weight, scaling_weight, regularization) -> None:
        self._gain_per_s = check_positive("gain_per_s (K)", gain_per_s, "1/s")
        self._task_weight = check_positive("task_weight (lambda1)", task_weight, "-")
        self.scaling_weight = check_positive(
            "scaling_weight (lambda2)", scaling_weight, "-", allow_zero=True
        )
        self.regularization = check_positive(
            "regularization (mu)", regularization, "-", allow_zero=True
        )

    def _check_stall(self, stall_damping, stall_scaling, stall_delay_s) -> None:
        self.stall_damping = check_positive(
            "stall_damping", stall_damping, "- (same unit as lambda1)", allow_zero=True
        )
        self.stall_scaling = check_positive("stall_scaling", stall_scaling, "-")
        if self.stall_scaling > 1.0:
            raise ParameterError(f"stall_scaling must be in (0, 1], got {stall_scaling!r}")
        self.stall_delay_s = check_positive("stall_delay_s", stall_delay_s, "s", allow_zero=True)

    def _set_acceleration(self, n: int, acceleration_limit, floor, cap) -> None:
        self.dynamic_acceleration = isinstance(acceleration_limit, str)
        self.a_const, floor, cap = acceleration_setting(acceleration_limit, n, floor, cap)
        if self.dynamic_acceleration:
            self.acceleration_floor, self.acceleration_cap = floor, cap

    # ------------------------------------------------------------------ composition
    def _layout(self, n: int, period_s: float) -> DecisionLayout:
        """Blocks at the instants ``τ_i``, each held until the next (the last as long as the
        one before; one block: one period)."""
        tau = self.instants_s
        if tau.size == 1:
            durations = np.array([float(period_s)])
        else:
            gaps = np.diff(tau)
            durations = np.append(gaps, gaps[-1])
        return DecisionLayout(n, tau, durations, with_scaling=True)

    def _compose_levels(self, layout, period_s: float, extra: tuple) -> tuple[Level, ...]:
        self._tracking = TrackingTerm(self._gain_per_s, self._task_weight)
        stall: tuple[Term, ...] = ()
        if self.scaling:
            delay = StallDampingTerm.delay_steps_for(self.stall_delay_s, float(period_s))
            self._stall = StallDampingTerm(layout, self.stall_damping, self.stall_scaling, delay)
            stall = (self._stall,)
        scaling = ScalingTerm(layout, self.scaling_weight)
        damping = DampingTerm(layout, self.regularization)
        if self.priority == "weighted":
            return (Level((self._tracking, scaling, damping, *stall, *extra), name="weighted"),)
        if not (self.regularization > 0.0 and self.scaling_weight > 0.0):
            raise ParameterError(
                "priority='strict' needs regularization > 0 and scaling_weight > 0 (each "
                f"level's cost must be strictly convex), got {self.regularization!r} and "
                f"{self.scaling_weight!r}"
            )
        mu = self.regularization
        tol = STRICT_TOLERANCE
        self._tracking.tangent = True  # the rows a level can hold (docs/theory.md §7.6)
        return (
            Level((self._tracking, DampingTerm(layout, mu, include_scaling=True)), tol,
                  "tracking"),
            Level((scaling, DampingTerm(layout, mu)), tol, "scaling"),
            Level((DampingTerm(layout, mu, include_scaling=True), *stall, *extra), tol,
                  "damping"),
        )  # fmt: skip

    def _compose_limits(self, layout, period_s: float) -> tuple[Limit, ...]:
        s_min = 0.0 if self.scaling else 1.0
        applied, predicted = self._joint_boxes
        acceleration = AccelerationLimit(layout, period_s, np.diff(self.instants_s))
        return (
            CommandBoxLimit(applied, acceleration),
            *((predicted,) if self.p > 1 else ()),
            ScalingRange(layout, s_min, 1.0),
        )

    # ------------------------------------------------------------------ the step's pieces
    def _acceleration(self, q_lin: np.ndarray) -> np.ndarray:
        if self.a_const is not None:
            return self._a_batch
        return self.robot.fast.acceleration_limits_batch(
            q_lin, 1.0, self.acceleration_floor, self.acceleration_cap
        )

    def _acceleration_is_constant(self) -> bool:
        return self.a_const is not None

    def _scaled(self) -> bool:
        return self.scaling

    # ------------------------------------------------------------------ parameters
    @property
    def gain_per_s(self) -> float:
        """Task-error gain ``K`` [1/s]."""
        return self._tracking.gain_per_s

    @gain_per_s.setter
    def gain_per_s(self, value: float) -> None:
        self._tracking.gain_per_s = float(value)

    @property
    def task_weight(self) -> float:
        """``λ1``."""
        return self._tracking.weight

    @task_weight.setter
    def task_weight(self, value: float) -> None:
        self._tracking.weight = float(value)
