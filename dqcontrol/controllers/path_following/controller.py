"""The path-following predictive controller (docs/theory.md §8).

A composition on the QP core: the consistent prediction (states exact and linear in the
decision ``qd_i``, ``s_i`` held over the horizon's intervals), and three priority levels:

1. the path: the linearised tangent error at every predicted state
   (:class:`~dqcontrol.controllers.terms.path_error.PathErrorTerm`);
2. progress: the time scaling towards 1 (or up to ``s_max`` to catch up), smoothly;
3. posture: joint velocities towards the start posture, in what the path leaves free;
   while the task is stalled (``s`` ≈ 0 for half a second: an unreachable path point, an
   obstacle) this level holds the arm still instead.

Limits, all exact and linear: velocity on every interval, position at every predicted
state, acceleration between intervals (the first from the applied command, with the
conflict rule), ``0 ≤ s_i ≤ s_max``, the phase within the task, and a terminal braking
condition. Where the linearisation is poor (the first step, after a fallback, after a
disturbance) the step re-linearises at its own solution and solves again, a bounded number
of times.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np

from dqcontrol._blas import single_blas_thread
from dqcontrol.controllers.base import (
    StepResult,
    acceleration_setting,
    check_positive,
    joint_limit_settings,
)
from dqcontrol.controllers.core.context import StepContext, aligned_kinematics
from dqcontrol.controllers.core.problem import Level, Problem, Residual
from dqcontrol.controllers.core.state_rows import state_rows_into
from dqcontrol.controllers.limits.acceleration import AccelerationLimit
from dqcontrol.controllers.limits.applied_box import AppliedCommandBox
from dqcontrol.controllers.limits.jerk import jerk_limits, jerk_setting
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.limits.phase_end import PhaseEndLimit
from dqcontrol.controllers.limits.phase_rest import PhaseRestLimit
from dqcontrol.controllers.limits.predicted_position import PredictedPositionLimit
from dqcontrol.controllers.limits.scaling_range import ScalingRange
from dqcontrol.controllers.limits.servo_lag import ServoLagMargin
from dqcontrol.controllers.limits.torque import TorqueLimit
from dqcontrol.controllers.limits.trust_region import TrustRegionLimit
from dqcontrol.controllers.limits.velocity import VelocityLimit
from dqcontrol.controllers.path_following.kernels import (
    tangent_mismatch,
)
from dqcontrol.controllers.path_following.kinematics_memo import KinematicsMemo
from dqcontrol.controllers.path_following.stillness import hold_still
from dqcontrol.controllers.path_following.tuning import PathFollowingTuning
from dqcontrol.controllers.prediction.base import Prediction
from dqcontrol.controllers.prediction.consistent import (
    ConsistentPrediction,
    interval_breakpoints,
)
from dqcontrol.controllers.prediction.distance import max_abs_difference
from dqcontrol.controllers.qp_controller import QPController, Remedy, Solved
from dqcontrol.controllers.terms.braking import BrakingTerm
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.controllers.terms.path_error import PROJECTOR_BASIS, PathErrorTerm
from dqcontrol.controllers.terms.posture import PostureTerm
from dqcontrol.controllers.terms.progress import ProgressTerm
from dqcontrol.controllers.terms.scaling_smoothness import ScalingSmoothnessTerm
from dqcontrol.controllers.terms.singularity_damping import SingularityDampingTerm
from dqcontrol.controllers.terms.term import Term
from dqcontrol.errors import ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = ["PathFollowingController"]

#: Weight of the path error against its level's damping (docs/theory.md §8.2).
PATH_WEIGHT = 1e4
#: ``ε`` and ``λ_max`` of the singularity damping (docs/theory.md §8.3).
SINGULAR_THRESHOLD = 0.04
SINGULAR_DAMPING = 0.04

#: The task counts as stalled while the applied ``s`` stays below this.
STALL_SCALING = 0.01
#: How long a stall must last before the posture level holds the arm still [s]: a task
#: that starts slowly is not a stalled one.
STALL_DELAY_S = 0.5
#: Factor on the path level's tolerance while stalled.
STALL_TIGHTENING = 0.01
#: Weight of the joint velocities beside the braking rows during a stop: with the level's
#: usual ``μ`` the tool brakes faster by moving the joints in the path's null space, which
#: then take as long again to stop (docs/theory.md §8.10).
STOP_DAMPING = 1e-2
#: The step's message after the path level was infeasible, by what regained feasibility
#: (the slack in mrad is formatted in).
_LOOSENED = "predicted position bounds loosened by {:g} mrad to regain feasibility"
_DROPPED = "predicted position bounds dropped to regain feasibility"


def _in_range(name: str, value: float, low: float, high: float, unit: str) -> float:
    """``value`` as a float in ``(low, high]`` (``[1, high]`` for ``low = 1``), or a
    :class:`ParameterError` naming it and the range."""
    v = check_positive(name, value, unit)
    if not (low < v <= high or v == low == 1.0):
        bracket = "[" if low == 1.0 else "("
        raise ParameterError(f"{name} must be in {bracket}{low:g}, {high:g}], got {value!r}")
    return v


def _checked_options(
    tuning: PathFollowingTuning | None, torque_limit_fraction: float | None
) -> tuple[PathFollowingTuning, float | None]:
    """The tuning (default :class:`PathFollowingTuning`) and the torque share, checked."""
    checked = PathFollowingTuning() if tuning is None else tuning
    if not isinstance(checked, PathFollowingTuning):
        raise ParameterError(f"tuning must be a PathFollowingTuning, got {type(tuning).__name__}")
    if torque_limit_fraction is None:
        return checked, None
    return checked, _in_range("torque_limit_fraction", torque_limit_fraction, 0.0, 1.0, "-")


def _tightened(levels: tuple[Level, ...]) -> tuple[Level, ...]:
    """The levels with the path level's band :data:`STALL_TIGHTENING` times narrower: while
    stalled, a drift within the band, step after step, would otherwise slide the tool along
    the path's tolerance (docs/theory.md §8.3)."""
    path = levels[0]
    return (dataclasses.replace(path, tolerance=STALL_TIGHTENING * path.tolerance), *levels[1:])


def _braking(levels: tuple[Level, ...], layout) -> tuple[Level, ...]:
    """The levels of a stop: the progress level's progress term replaced by a braking one,
    its damping by :data:`STOP_DAMPING` and its smoothing of ``s`` dropped (the stop is as
    fast as the limits allow)."""
    path, progress, *rest = levels

    def stop_term(term: Term) -> Term:
        if isinstance(term, ProgressTerm):
            return BrakingTerm(layout)
        if isinstance(term, DampingTerm):
            return DampingTerm(layout, STOP_DAMPING)
        return term

    terms = tuple(stop_term(t) for t in progress.terms if not isinstance(t, ScalingSmoothnessTerm))
    return (path, dataclasses.replace(progress, terms=terms), *rest)


class PathFollowingController(QPController):
    """Path first, progress second, posture third, over a consistent prediction.

    Args:
        robot, trajectory, period_s: see :class:`~dqcontrol.controllers.base.Controller`.
        num_intervals: ``p ≥ 2`` intervals of the horizon (the first is ``T``; the others
            grow as a power of their index, :attr:`PathFollowingTuning.interval_growth`).
        horizon_s: ``τ_p`` [s], longer than ``T``.
        velocity_limits: ``qd_max`` [rad/s] (scalar or per joint); default: the URDF's.
        acceleration_limit: ``"dynamics"`` (default: Pinocchio's ``(τ_max - |g|)/M_jj`` at
            each interval's predicted state, clipped to ``[acceleration_floor,
            acceleration_cap]``) or a constant [rad/s²] (scalar or per joint).
        position_margin_rad: the position bounds stop this far inside the URDF's [rad].
        s_max: largest time scaling (1; up to 1.5 lets a late task catch up).
        posture_gain_per_s: rate of the pull towards the start posture [1/s].
        posture_reference: ``"start"`` (the configuration at reset) or a configuration.
        end: ``"rest"`` (default: the phase velocity brakes to 0 exactly at ``σ = T_tot``
            within the limits, :class:`~dqcontrol.controllers.limits.phase_rest.
            PhaseRestLimit`) or ``"at_speed"`` (the thesis's convention: the task ends at
            the nominal speed; :meth:`request_stop` then brings the arm to rest).
        jerk_limit: jerk bound of the commanded velocity [rad/s³] (scalar or per joint);
            default: the robot's ``limits.qddd_max`` (no jerk rows where it is infinite).
        torque_limit_fraction: bound the joint torques of the plan through the inverse
            dynamics to this share of the URDF's effort limits (``None``: no torque rows).
        servo_time_constant_s: the joints follow each new velocity command as a first-order
            lag of this time constant ``τ_v`` [s] (a velocity servo); the prediction includes
            it, starting from the measured velocity (0: ideal velocity tracking). A command
            step ``Δ`` then asks the servo for ``Δ/τ_v`` at once, so the dynamics-aware
            acceleration limit is scaled by ``min(1, τ_v/T)`` (a constant one is taken as
            given).
        tuning: the expert settings (tolerances, linearisation rounds, trust region,
            acceleration reserve): :class:`PathFollowingTuning`, whose defaults are the
            measured choices of docs/theory.md §8.
        extra_terms: more terms, added to the lowest (posture) level.
        extra_limits: more limits (any :class:`~dqcontrol.controllers.limits.limit.Limit`).
        solver: a registered backend's name (``"daqp"``, the default, or ``"osqp"``:
            :func:`~dqcontrol.controllers.backends.base.backend_names`);
            ``solver_settings`` for it.

    Attributes:
        backend: the :class:`~dqcontrol.controllers.backends.base.Backend` every level of
            every step is solved by; it may be replaced by a wrapper (a
            :class:`~dqcontrol.controllers.backends.base.ForwardingBackend`).
    """

    name = "path_following"
    stops_itself = True
    prediction_model: ConsistentPrediction

    def __init__(
        self,
        robot: RobotModel,
        trajectory: Trajectory,
        period_s: float,
        *,
        num_intervals: int = 10,
        horizon_s: float = 1.0,
        velocity_limits: float | np.ndarray | None = None,
        acceleration_limit: float | np.ndarray | Literal["dynamics"] = "dynamics",
        acceleration_floor: float = 0.5,
        acceleration_cap: float = 50.0,
        position_margin_rad: float = 5e-3,
        s_max: float = 1.0,
        posture_gain_per_s: float = 1.0,
        posture_reference: Literal["start"] | np.ndarray = "start",
        end: Literal["rest", "at_speed"] = "rest",
        jerk_limit: float | np.ndarray | None = None,
        torque_limit_fraction: float | None = None,
        servo_time_constant_s: float = 0.0,
        tuning: PathFollowingTuning | None = None,
        measurement_delay_periods: int = 0,
        extra_terms: tuple[Term, ...] = (),
        extra_limits: tuple[Limit, ...] = (),
        solver: str | None = None,
        solver_settings: dict | None = None,
    ) -> None:
        super().__init__(
            robot, trajectory, period_s, measurement_delay_periods=measurement_delay_periods
        )
        self.horizon_s = check_positive("horizon_s (tau_p)", horizon_s, "s")
        self.tuning, self.torque_limit_fraction = _checked_options(tuning, torque_limit_fraction)
        self.s_max = _in_range("s_max", s_max, 1.0, 1.5, "-")
        self.position_margin_rad, self.q_min, self.q_max, self.qd_max = joint_limit_settings(
            robot, velocity_limits, position_margin_rad
        )
        self._set_acceleration(acceleration_limit, acceleration_floor, acceleration_cap)
        self.jerk_max = jerk_setting(robot, jerk_limit)
        growth = self.tuning.growth_for(
            self.horizon_s, self.period_s, num_intervals, self._turn_time_s()
        )
        breaks = interval_breakpoints(num_intervals, self.horizon_s, self.period_s, growth)
        self.num_intervals = int(num_intervals)
        self._set_servo(servo_time_constant_s, breaks)
        self.posture = PostureTerm(self.layout, posture_gain_per_s)
        self._posture_reference = posture_reference
        levels = self._levels(tuple(extra_terms))
        self._stalled_levels = _tightened(levels)
        self._stop_levels = _braking(_tightened(levels), self.layout)
        self._stall_steps = int(np.ceil(STALL_DELAY_S / self.period_s - 1e-9))
        self._a_max_key: tuple = (None, np.zeros((0, self.n)))
        self._memo = KinematicsMemo(self.robot)
        prediction = self.prediction_model
        limits = self._limits() + self._end_limits(end) + tuple(extra_limits)
        self.compose(prediction, levels, limits, solver, solver_settings, self.s_max)
        self._set_servo_lag()
        self._reset_state()

    # ------------------------------------------------------------------ composition
    def _remedies(self) -> tuple[Remedy, ...]:
        """An infeasible path level is solved again with the predicted position rows
        loosened by ``position_slack_rad``, then without them (docs/theory.md §8.6)."""
        slack = self.tuning.position_slack_rad
        loosened = tuple(
            lim.widened(slack) if isinstance(lim, PredictedPositionLimit) else lim
            for lim in self.limits
        )
        dropped = tuple(lim for lim in self.limits if not isinstance(lim, PredictedPositionLimit))
        return (
            Remedy("loosened", loosened, _LOOSENED.format(slack * 1e3)),
            Remedy("dropped", dropped, _DROPPED),
        )

    def _set_servo(self, time_constant_s: float, breaks: np.ndarray) -> None:
        """The prediction (with the servo's lag) and the share of the dynamics-aware
        acceleration a command step may use behind the servo."""
        self.servo_time_constant_s = check_positive(
            "servo_time_constant_s", time_constant_s, "s", allow_zero=True
        )
        # behind a servo of time constant τ_v a command step of Δ asks for Δ/τ_v at once:
        # over a period T the mean acceleration is then held to τ_v/T of what the torques allow
        tau_v = self.servo_time_constant_s
        self._servo_share = min(1.0, tau_v / self.period_s) or 1.0
        # the first-order lag is predicted only where the servo settles within a period
        # (T > τ_v); a slower servo's integral action makes its response over a few periods
        # differ from a first-order lag, and the loop closes faster than it (theory §8.7)
        lag_s = tau_v if tau_v < self.period_s else 0.0
        self.prediction_model = ConsistentPrediction(
            breaks, self.n, self.period_s, self.s_max, lag_s
        )
        self.layout = self.prediction_model.layout

    def _set_servo_lag(self) -> None:
        """The position rows' bounds moved by the servo's measured lag, as the thesis's
        controllers' are (:class:`~dqcontrol.controllers.limits.servo_lag.ServoLagMargin`;
        docs/theory.md §8.7)."""
        lim = self.robot.limits
        self._positions = next(x for x in self.limits if isinstance(x, PredictedPositionLimit))
        self._position_bounds = np.vstack([self.q_min, self.q_max, self.qd_max])
        self._servo_lag = ServoLagMargin(
            lim.q_min, lim.q_max, self.position_margin_rad, self.period_s, self.a_const
        )

    def _set_acceleration(self, acceleration_limit, floor: float, cap: float) -> None:
        self.dynamic_acceleration = isinstance(acceleration_limit, str)
        self.a_const, floor, cap = acceleration_setting(acceleration_limit, self.n, floor, cap)
        if self.dynamic_acceleration:
            self.acceleration_floor, self.acceleration_cap = floor, cap

    def _turn_time_s(self) -> float | None:
        """``2 min_j ā_j/j̄_j`` [s] over the joints with a jerk bound: the shortest time a
        joint's acceleration takes to turn from one bound to the other (``None`` without a
        jerk bound)."""
        a_bar, jerk = self._jerk_accelerations(), self.jerk_max
        if a_bar is None or jerk is None:
            return None
        bounded = np.isfinite(jerk)
        return float(2.0 * np.min(a_bar[bounded] / jerk[bounded]))

    def _jerk_accelerations(self) -> np.ndarray | None:
        """``ā`` per joint [rad/s²] under a jerk bound (``None`` without one): the constant
        bound, or the dynamics-aware bound's cap (the robot's profile where it gives one)."""
        if self.jerk_max is None:
            return None
        if self.a_const is not None:
            return np.broadcast_to(self.a_const, (self.n,))
        qdd_max = self.robot.limits.qdd_max
        assert qdd_max is not None, "JointLimits fills it"
        return np.minimum(self.acceleration_cap, qdd_max)

    def _levels(self, extra: tuple[Term, ...]) -> tuple[Level, ...]:
        layout, mu, tuning = self.layout, self.tuning.damping, self.tuning
        path_tol, progress_tol = tuning.path_tolerance, tuning.progress_tolerance
        first = float(layout.durations_s[0])
        self.singularity = SingularityDampingTerm(
            layout, SINGULAR_THRESHOLD, SINGULAR_DAMPING, PATH_WEIGHT * first * first
        )
        path = Level(
            (
                PathErrorTerm(PATH_WEIGHT, tuning.path_full_weight_time_s),
                DampingTerm(layout, mu, include_scaling=True),
            ),
            path_tol,
            "path",
        )
        progress = Level(
            (
                ProgressTerm(layout, self.s_max),
                ScalingSmoothnessTerm(layout),
                DampingTerm(layout, mu),
                self.singularity,
            ),
            progress_tol,
            "progress",
        )
        posture = Level((self.posture, DampingTerm(layout, mu), *extra), 1e-6, "posture")
        return path, progress, posture

    def _reserve(self) -> float:
        """The share of ``a_max`` the coupling rows allow
        (:meth:`PathFollowingTuning.reserve_for`); under a jerk bound, by default, at least
        what lets the plan's second acceleration leave the bound within the first jerk
        row from an applied one at ``ā``: ``1 - min_j j̄_j m_0/ā_j``, ``m_0 = ½(T + h_1)``
        (docs/theory.md §8.11)."""
        durations = self.layout.durations_s
        reserve = self.tuning.reserve_for(self.period_s, float(durations[1]))
        a_bar, jerk = self._jerk_accelerations(), self.jerk_max
        if a_bar is None or jerk is None or self.tuning.acceleration_reserve is not None:
            return reserve
        m_0 = 0.5 * (self.period_s + 0.5 * float(durations[0] + durations[1]))
        bounded = np.isfinite(jerk)
        reach = np.min(jerk[bounded] * m_0 / a_bar[bounded])
        return max(reserve, min(1.0, 1.0 - float(reach)))

    def _limits(self) -> tuple[Limit, ...]:
        layout = self.layout
        self._trust = TrustRegionLimit(
            layout,
            self.tuning.trust_radius_rad,
            self.tuning.trust_radius_phase_s,
            self.tuning.trust_growth_time_s,
        )
        durations = layout.durations_s
        coupling = 0.5 * (durations[1:] + durations[:-1])
        torque: tuple[Limit, ...] = ()
        if self.torque_limit_fraction is not None:
            effort = self.robot.limits.effort_max
            torque = (
                TorqueLimit(
                    layout,
                    self.period_s,
                    coupling,
                    effort,
                    self.torque_limit_fraction,
                    self.servo_time_constant_s or None,
                ),  # fmt: skip
            )
        return torque + (
            VelocityLimit(layout, self.qd_max),
            AppliedCommandBox(layout, self.q_min, self.q_max, self.qd_max, self.period_s),
            ScalingRange(layout, 0.0, self.s_max),
            AccelerationLimit(layout, self.period_s, coupling, self._reserve()),
            *jerk_limits(
                self.jerk_max,
                layout,
                self.period_s,
                self.qd_max,
                self.q_min,
                self.q_max,
                coupling,
                self.acceleration_cap if self.a_const is None else self.a_const,
            ),  # fmt: skip
            PredictedPositionLimit(
                layout,
                self.q_min,
                self.q_max,
                self.qd_max,
                reach_rad=self._trust.radii_rad,
                jerk_max=self.jerk_max,
            ),
            PhaseEndLimit(layout),
            self._trust,
        )

    def _end_limits(self, end: str) -> tuple[Limit, ...]:
        """The rows that end the task at rest (``end="rest"``), or none (``"at_speed"``)."""
        if end not in ("rest", "at_speed"):
            raise ParameterError(f"end must be 'rest' or 'at_speed', got {end!r}")
        self.end = end
        self.ends_at_rest = end == "rest"
        self._rest: PhaseRestLimit | None = None
        if end == "at_speed":
            return ()
        self._rest = PhaseRestLimit(self.layout, self.s_max, self.tuning.rest_deceleration_share)
        return (self._rest,)

    def _posture_scale(self) -> float:
        """The share of the posture pull in force: none while stopping or stalled; towards
        a rest at the end, the share of its speed the phase may keep
        (:meth:`PhaseRestLimit.speed_share`), so that the motion in the path's null space
        comes to rest with the phase."""
        if self.stopping or self._stalled():
            return 0.0
        if self._rest is None:
            return 1.0
        return self._rest.speed_share(self.trajectory, self.sigma)

    # ------------------------------------------------------------------ the stop
    def _begin_stop(self) -> None:
        """The progress level's goal becomes ``s → 0`` (the path level kept, its band as
        narrow as while stalled; the posture level holds the arm still): the arm brakes
        along the path (docs/theory.md §8.10)."""
        self._levels_now = self._stop_levels

    # ------------------------------------------------------------------ memory
    def _reset_state(self) -> None:
        self._steps = 0
        self._stalled_steps = 0
        self._s_prev = 0.0
        self._expected_q: np.ndarray | None = None
        self._poor = True  # the first step linearises at rest: iterate

    def _reset_memory(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        super()._reset_memory(q0, qd0)
        if self._servo_lag.restore(self._position_bounds):
            self._positions.set_bounds(*self._position_bounds[:2])
        ref = self._posture_reference
        if isinstance(ref, str):
            if ref != "start":
                raise ParameterError(
                    f"posture_reference must be 'start' or a configuration, got {ref!r}"
                )
            self.posture.reference = q0.copy()
        else:
            self.posture.reference = self.robot.check_q(ref, "posture_reference")
        self._memo.clear()
        self._reset_state()
        self._levels_now = self.levels

    # ------------------------------------------------------------------ one step
    def _step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        """The step, the position rows' bounds first moved by the servo's measured lag
        (not with a compensated measurement delay, whose measured velocity is older than
        the command)."""
        measured = None if self.measurement_delay_periods else qd
        if self._servo_lag.update(measured, self.qd_prev, self._position_bounds):
            self._positions.set_bounds(*self._position_bounds[:2])
        with single_blas_thread():  # the dense levels' products and factorisations
            return super()._step(q, qd)

    def _step_context(self, q: np.ndarray, qd: np.ndarray | None) -> StepContext:
        """The context at the prediction from the measured state (``qd``: the measured
        velocities, where given; the servo's lag starts from them)."""
        self._memo.advance()
        model = self.prediction_model
        model.qd_measured = self.qd_prev if qd is None else qd
        return self._context_at(q, model.predict(q, self.sigma))

    def _context_at(self, q: np.ndarray, pred: Prediction) -> StepContext:
        xs, jacs, xd, dxd = aligned_kinematics(
            self.robot, self.trajectory, pred.q_lin, pred.sigma_lin
        )
        p = self.layout.num_blocks
        if self.a_const is not None:
            a_max = self._constant_a_max(self.a_const, p)
        else:
            starts = np.concatenate((q[None, :], pred.q_lin[:-1]))
            a_max = self.robot.fast.acceleration_limits_batch(
                starts, 1.0, self.acceleration_floor, self.acceleration_cap
            )
            if self._servo_share < 1.0:
                a_max = a_max * self._servo_share
        return StepContext(
            self.robot, self.trajectory, self.layout, self.period_s, q, self.qd_prev,
            self.sigma, pred, xs, jacs, xd, dxd, a_max,
            s_prev=self._s_prev,
            lag_s=self._steps * self.period_s - self.sigma,
            posture_scale=self._posture_scale(),
            qd_measured=self.prediction_model.qd_measured, qd_before_prev=self.qd_before_prev,
        )  # fmt: skip

    def _constant_a_max(self, a_const: np.ndarray, p: int) -> np.ndarray:
        """The constant ``a_max`` of every block ``(p, n)``, the same array at every step
        (the limits keep what they derive from it while it stays the same)."""
        key = self._a_max_key
        if key[0] is not a_const or key[1].shape[0] != p:
            self._a_max_key = (a_const, np.broadcast_to(a_const, (p, self.n)))
        return self._a_max_key[1]

    def _solve(self, ctx: StepContext) -> Solved:
        """Linearise and solve: where the linearisation is poor (the first step, after a
        fallback or a disturbance) or the first state's linearised path error is far from
        the true one, again at the plan just found, a bounded number of rounds
        (docs/theory.md §8.5)."""
        q, model, tuning = ctx.q, self.prediction_model, self.tuning
        poor = self._poor or self._disturbed(q)
        iterations, solve_time, levels_time, rounds = 0, 0.0, 0.0, 0
        while True:
            solved = super()._solve(ctx)
            rounds += 1
            iterations += solved.iterations
            solve_time += solved.solve_time_s
            levels_time += solved.levels_time_s
            result = solved.result
            if result.failed_level == 0 or rounds == tuning.max_linearisations:
                break
            z = result.solution.x
            assert z is not None, "a solved first level has its solution"
            if not poor and self._mismatch(q, solved.problem.problem(), z) < (
                tuning.linearisation_tolerance_m
            ):
                break
            qd_plan, s_plan = self.layout.split(z)
            assert s_plan is not None, "path following always scales time"
            warm_qd = ctx.prediction.warm_qd
            if poor and float(np.max(np.abs(qd_plan - warm_qd))) < tuning.linearisation_tolerance:
                break
            plan_s = np.clip(s_plan, 0.0, self.s_max)
            ctx = self._context_at(q, model.at(q, self.sigma, qd_plan.copy(), plan_s))
        return solved._replace(
            iterations=iterations, solve_time_s=solve_time, rounds=rounds,
            levels_time_s=levels_time,
        )  # fmt: skip

    def _stalled(self) -> bool:
        """``s`` has stayed below :data:`STALL_SCALING` for :data:`STALL_DELAY_S`."""
        return self._stalled_steps >= self._stall_steps

    def _disturbed(self, q: np.ndarray) -> bool:
        if self._expected_q is None:
            return True
        return max_abs_difference(q, self._expected_q) > self.tuning.relinearise_threshold_rad

    def _mismatch(self, q: np.ndarray, problem: Problem, z: np.ndarray) -> float:
        """How far the linearised path error of the first predicted state is from the
        true one (tangent units: half-radians and half-metres)."""
        path = problem.levels[0].residuals[0]
        q1 = self.prediction_model.state_after_first(q, z[: self.n])
        sigma1 = self.sigma + self.period_s * min(max(float(z[self.n]), 0.0), self.s_max)
        x1 = self.robot.fast.poses(q1[None, :])[0]
        xd1 = self.trajectory.target(sigma1)
        self._memo.keep_pose(q1, x1)  # the next measured q, in a simulated loop
        self._memo.keep_target(self.trajectory, sigma1, xd1)
        rows = self._first_rows(path)
        return tangent_mismatch(x1, xd1, PROJECTOR_BASIS, rows, path.b, z[: rows.shape[1]])

    def _first_rows(self, path: Residual) -> np.ndarray:
        """The path rows of the first predicted state over the first decision block
        ``(6, n + 1)`` (the state after the first interval reads no later block), or over
        every variable where the rows are given dense."""
        if path.states is None:
            return path.dense(self.layout)
        st = path.states
        r, m = st.rows.shape[1:]
        rows = np.empty((1, r, 1, m))
        state_rows_into(st.rows[:1], st.weights[:1, :1], st.phase_weights[:1, :1], rows)
        return rows.reshape(r, m)

    def _finish(self, solved: Solved, start: float) -> StepResult:
        """The result, then what the next step needs: where the command takes the arm (the
        disturbance check), the applied ``s``, the clock and the stall count; a fallback
        makes the next linearisation poor. While stalled, a plan that does not progress
        stands still (:func:`~.stillness.hold_still`)."""
        if self._stalled():
            hold_still(solved, self.n, STALL_SCALING)
        self._reported = self._pose_target(solved.problem.ctx.q)
        result = super()._finish(solved, start)
        qd_cmd, s_now = result.qd_command, result.s
        self._expected_q = self.prediction_model.state_after_first(solved.problem.ctx.q, qd_cmd)
        self._s_prev = s_now
        self._steps += 1
        moving = s_now >= STALL_SCALING or self.sigma == 0.0
        self._stalled_steps = 0 if moving else self._stalled_steps + 1
        self._poor = result.diagnostics.fallback
        # the path's band narrower while the task is stalled
        if self.stopping:
            self._levels_now = self._stop_levels
        else:
            self._levels_now = self._stalled_levels if self._stalled() else self.levels
        return result

    def _pose_target(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pose at the measured ``q`` (kept from the last step's check where it was
        predicted there) and the target now, the pose's sign aligned to it."""
        x0 = self._memo.pose(q)
        xd0 = self._memo.target(self.trajectory, self.sigma)
        if float(x0.dot(xd0)) < 0.0:
            x0 = -x0
        return x0, xd0
