"""The one interface of every controller (docs/theory.md §4).

A controller is reset with the initial state, then called once per control period ``T``
with the measured joint positions (and velocities); it returns the joint-velocity command,
the time scaling ``s`` applied, the phase ``σ`` used, and diagnostics. A controller never
raises from inside :meth:`Controller.step` because a QP failed: it falls back to a safe
command and says so in :class:`StepDiagnostics`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from dqcontrol.errors import ConfigurationError, ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.streaming.streamed import StreamedController

_T = TypeVar("_T")

_FLOAT = np.dtype(float)

__all__ = [
    "Controller",
    "StepDiagnostics",
    "StepResult",
    "acceleration_setting",
    "robot_acceleration_limit",
    "check_position_margin",
    "check_positive",
    "joint_limit_settings",
    "fast_constructor",
    "per_joint",
]


@dataclass(frozen=True)
class StepDiagnostics:
    """What happened inside one control step.

    Attributes:
        status: solver status (``"solved"``, ``"primal_infeasible"`` ...) or ``"closed_form"``.
        iterations: solver iterations (0 for closed-form controllers).
        solve_time_s: time spent in the solver [s].
        step_time_s: time of the whole step, prediction and QP build included [s].
        fallback: the safe fallback command was used (the QP failed).
        relaxed: the predicted instants' position bounds were dropped to regain feasibility.
        saturated: the command was clipped to the hard bounds (proportional controller).
        conflict_joints: joints whose acceleration and position bounds conflicted.
        message: a human-readable note when something was unusual.
        linearisations: linearise-and-solve rounds of this step (1 for the thesis's
            controllers; up to the controller's bound where the linearisation is poor).
        levels_time_s: time of the prioritised solve [s] (controllers with priority
            levels: every level's reduction to the null space of the rows held above and
            its solver call, ``solve_time_s`` being the solver calls alone; 0 otherwise).
    """

    status: str
    iterations: int = 0
    solve_time_s: float = 0.0
    step_time_s: float = 0.0
    fallback: bool = False
    relaxed: bool = False
    saturated: bool = False
    conflict_joints: tuple[int, ...] = ()
    message: str = ""
    linearisations: int = 1
    levels_time_s: float = 0.0


@dataclass(frozen=True)
class StepResult:
    """The output of one control step.

    Attributes:
        qd_command: joint-velocity command to hold for one period [rad/s], shape ``(n,)``.
        s: time scaling applied during this period (``0 ≤ s ≤ 1``).
        sigma: phase ``σ_k`` of the target used in this step [s of nominal time].
        sigma_next: ``σ_{k+1} = σ_k + T s`` (eq. 3.3).
        pose: measured end-effector pose ``x_k`` (vec8, sign-aligned to the target).
        target: target pose ``x_d(σ_k)`` (vec8).
        diagnostics: :class:`StepDiagnostics`.
        horizon_qd: predicted commands at the prediction instants ``(p, n)`` (predictive
            controllers; ``None`` otherwise). The predictor's state, not a plan: the later
            instants may alternate from one step to the next (docs/theory.md §4.3).
        horizon_s: predicted scalings ``(p,)`` (predictive controllers).
    """

    qd_command: np.ndarray
    s: float
    sigma: float
    sigma_next: float
    pose: np.ndarray
    target: np.ndarray
    diagnostics: StepDiagnostics
    horizon_qd: np.ndarray | None = field(default=None, repr=False)
    horizon_s: np.ndarray | None = field(default=None, repr=False)


def check_positive(name: str, value: float, unit: str, *, allow_zero: bool = False) -> float:
    """Return ``value`` as float or raise :class:`ParameterError` naming it and the range."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number [{unit}], got {value!r}") from None
    ok = math.isfinite(v) and (v >= 0.0 if allow_zero else v > 0.0)
    if not ok:
        rng = "≥ 0" if allow_zero else "> 0"
        raise ParameterError(f"{name} must be finite and {rng} [{unit}], got {value!r}")
    return v


def per_joint(name: str, value, n: int, unit: str, *, allow_zero: bool = False) -> np.ndarray:
    """``value`` (a scalar or one value per joint) as an array of shape ``(n,)``.

    Raises :class:`ParameterError` naming the parameter, the accepted shapes, unit and range
    for a wrong shape, a non-number, NaN/inf, or a value out of range (> 0, or ≥ 0).
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(
            f"{name} must be a number or {n} numbers [{unit}], got {value!r}"
        ) from None
    if arr.ndim > 1 or (arr.ndim == 1 and arr.size != n):
        raise ParameterError(
            f"{name} must be a scalar or have shape ({n},) (one per joint) [{unit}], "
            f"got shape {arr.shape}"
        )
    arr = np.broadcast_to(arr, (n,)).copy()
    ok = np.isfinite(arr) & ((arr >= 0.0) if allow_zero else (arr > 0.0))
    if not ok.all():
        rng = "≥ 0" if allow_zero else "> 0"
        raise ParameterError(f"{name} must be finite and {rng} [{unit}], got {value!r}")
    return arr


def acceleration_setting(
    acceleration_limit, n: int, floor: float, cap: float
) -> tuple[np.ndarray | None, float, float]:
    """``(a_const, floor, cap)`` of a controller's ``acceleration_limit``: a constant
    [rad/s²] (scalar or per joint) gives ``a_const``; ``"dynamics"`` gives ``a_const = None``
    and the validated ``floor ≤ cap`` [rad/s²] of the dynamics-aware bound (docs/theory.md
    §5). Anything else: :class:`ParameterError` naming the parameter and what it accepts."""
    if not isinstance(acceleration_limit, str):
        return (
            per_joint("acceleration_limit", acceleration_limit, n, "rad/s² (or 'dynamics')"),
            floor,
            cap,
        )
    if acceleration_limit != "dynamics":
        raise ParameterError(
            "acceleration_limit must be a positive number [rad/s²], one per joint, or "
            f"'dynamics', got {acceleration_limit!r}"
        )
    floor_v = check_positive("acceleration_floor", floor, "rad/s^2")
    cap_v = check_positive("acceleration_cap", cap, "rad/s^2")
    if floor_v > cap_v:
        raise ParameterError(
            f"acceleration_floor ({floor}) must be ≤ acceleration_cap ({cap}) [rad/s²]"
        )
    return None, floor_v, cap_v


def robot_acceleration_limit(robot: RobotModel, acceleration_limit, default):
    """A controller's ``acceleration_limit`` when the user gave one, else the robot's: its
    limit profile's ``qdd_max`` [rad/s²] where finite, ``default`` for the other joints
    (``default`` alone when the profile gives none, e.g. the URDF's limits). With a
    ``"dynamics"`` default the robot's model caps the bound itself
    (:meth:`~dqcontrol.model.robot.RobotModel.acceleration_limits`)."""
    if acceleration_limit is not None:
        return acceleration_limit
    qdd_max = robot.limits.qdd_max
    assert qdd_max is not None, "JointLimits fills it"
    finite = np.isfinite(qdd_max)
    if isinstance(default, str) or not finite.any():
        return default
    return np.where(
        finite, qdd_max, np.broadcast_to(np.asarray(default, dtype=float), qdd_max.shape)
    )


def check_position_margin(margin_rad: float, q_min: np.ndarray, q_max: np.ndarray) -> float:
    """Validate the joint-position margin [rad]: ``0 ≤ margin < (q_max - q_min) / 2``."""
    m = check_positive("position_margin_rad", margin_rad, "rad", allow_zero=True)
    half = float(np.min(q_max - q_min)) / 2.0
    if m >= half:
        raise ParameterError(
            f"position_margin_rad must be < half the smallest joint range ({half:.4g} rad), "
            f"got {margin_rad!r}"
        )
    return m


def joint_limit_settings(
    robot: RobotModel, velocity_limits, position_margin_rad: float
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """``(margin, q_min, q_max, qd_max)``: the URDF's position limits shrunk by the checked
    margin [rad], and ``velocity_limits`` [rad/s] (scalar or per joint; ``None``: the URDF's,
    which must then be positive and finite)."""
    lim = robot.limits
    margin = check_position_margin(position_margin_rad, lim.q_min, lim.q_max)
    if velocity_limits is None:
        qd_max = lim.qd_max.copy()
        if np.any(qd_max <= 0.0) or not np.all(np.isfinite(qd_max)):
            raise ParameterError(
                "the URDF gives no positive velocity limit for some joints "
                f"({lim.qd_max}); pass velocity_limits [rad/s]"
            )
    else:
        qd_max = per_joint("velocity_limits", velocity_limits, robot.nq, "rad/s")
    return margin, lim.q_min + margin, lim.q_max - margin, qd_max


def fast_constructor(cls: type[_T], **required: object) -> Callable[..., _T]:
    """A constructor of the frozen dataclass ``cls`` that fills the instance's ``__dict__``
    in one update instead of one ``object.__setattr__`` per field: for the results of the
    1 kHz control steps.

    The defaults come from an instance built by ``cls(**required)``; the result is the
    same object ``cls(**fields)`` would build. ``cls`` itself is returned where that
    would not hold (slots, or a ``__post_init__``).
    """
    template = cls(**required)
    if not hasattr(template, "__dict__") or hasattr(cls, "__post_init__"):
        return cls
    defaults = dict(vars(template))
    new = object.__new__

    def make(**fields: object) -> _T:
        obj: _T = new(cls)
        attrs = vars(obj)
        attrs.update(defaults)
        attrs.update(fields)
        return obj

    return make


class Controller(ABC):
    """Base class of the four controllers.

    Args:
        robot: the robot model (Pinocchio, vec8 kinematics).
        trajectory: the task; if its ``reference`` is ``None`` it is anchored at the
            robot's pose at :meth:`reset` (the default reference frame of docs/theory.md §3).
        period_s: control period ``T`` [s].
        measurement_delay_periods: ``d ≥ 0``; when the measured ``q`` is ``d`` periods old,
            the controller works from ``q + T Σ(last d commands)``, its prediction of the
            present (default 0: no compensation; a joint may then pass its limit by up to
            ``d T qd_max``).
    """

    #: Short name used in logs and tables.
    name: str = "controller"
    #: Whether :meth:`request_stop` is handled by the controller's own steps (else by a
    #: path-following controller's stop on the same task).
    stops_itself: bool = False
    #: Whether the controller's own steps bring the phase to rest at ``σ = T_tot`` (else
    #: its task ends at speed, the thesis's convention; :meth:`finish_at_rest` ends it at
    #: rest).
    ends_at_rest: bool = False

    def __init__(
        self,
        robot: RobotModel,
        trajectory: Trajectory,
        period_s: float,
        measurement_delay_periods: int = 0,
    ) -> None:
        if not isinstance(robot, RobotModel):
            raise ParameterError(
                f"robot must be a dqcontrol RobotModel, got {type(robot).__name__}"
            )
        if not isinstance(trajectory, Trajectory):
            raise ParameterError(
                f"trajectory must be a dqcontrol Trajectory, got {type(trajectory).__name__}"
            )
        self.robot = robot
        self.task = trajectory  # as given (maybe unanchored)
        self.trajectory = trajectory  # as used (anchored at reset when needed)
        self.period_s = check_positive("period_s (T)", period_s, "s")
        self.n = robot.nq
        self.sigma = 0.0
        #: the time scaling ``s`` of the last step (the phase rate a stream taking over holds)
        self.s_last = 0.0
        self.qd_prev = np.zeros(self.n)
        if (
            isinstance(measurement_delay_periods, bool)
            or not isinstance(measurement_delay_periods, int | np.integer)
            or measurement_delay_periods < 0
        ):
            raise ParameterError(
                "measurement_delay_periods must be an integer ≥ 0 [periods], got "
                f"{measurement_delay_periods!r}"
            )
        self.measurement_delay_periods = int(measurement_delay_periods)
        self._sent: deque[np.ndarray] = deque(maxlen=max(self.measurement_delay_periods, 1))
        self._reset_done = False
        self._q_shape = (self.n,)
        #: Whether a stop was requested (:meth:`request_stop`) since the last reset.
        self.stopping = False
        #: The controller whose steps are this one's after :meth:`request_stop` or
        #: :meth:`finish_at_rest` (``None``: its own).
        self._delegate: Controller | None = None
        #: A streamed end at rest that :meth:`finish_at_rest` hands over to
        #: (:func:`~dqcontrol.streaming.end.end_stream`, set by ``run_loop`` on the wall
        #: clock); ``None``: the end is a path-following controller stepped here.
        self.end_stream: StreamedController | None = None

    def reset(self, q0: np.ndarray, qd0: np.ndarray | None = None, sigma0: float = 0.0) -> None:
        """Start a new run from joint positions ``q0`` [rad] (and velocity ``qd0`` [rad/s]).

        Anchors the trajectory at the pose of ``q0`` if it has no reference yet, sets
        ``σ = sigma0`` and takes ``qd0`` (default zero) as the previous command.
        """
        q0 = self.robot.check_q(q0, "q0")
        qd0 = np.zeros(self.n) if qd0 is None else self.robot.check_q(qd0, "qd0")
        if self.task.reference is None:
            self.trajectory = self.task.anchored_at(self.robot.pose(q0))
        else:
            self.trajectory = self.task
        self.sigma = check_positive("sigma0", sigma0, "s", allow_zero=True)
        self.s_last = 0.0
        self.qd_prev = qd0.copy()
        self._sent.clear()
        self._reset_done = True
        self.stopping = False
        self._delegate = None
        self._reset_memory(q0, qd0)

    def _reset_memory(self, q0: np.ndarray, qd0: np.ndarray) -> None:  # noqa: B027
        """Hook for controllers with more memory (the predictive horizon); none by default."""

    def request_stop(self) -> None:
        """Bring the arm to rest along the path, as fast as the limits allow
        (docs/theory.md §8.10): every later :meth:`step` brakes the phase to ``s = 0`` with
        the path kept. Here, the steps are those of a path-following controller on the same
        task, robot, period and bounds, started at this controller's phase and last command
        (:func:`~dqcontrol.controllers.stop_delegate.stop_delegate`); a controller that
        stops by itself (``stops_itself``) overrides :meth:`_begin_stop`."""
        if not self._reset_done:
            raise ConfigurationError("call reset(q0) before request_stop()")
        if not self.stopping:
            self.stopping = True
            if self._delegate is not None:  # ending at rest: its delegate stops
                self._delegate.request_stop()
            else:
                self._begin_stop()

    def finish_at_rest(self, q: np.ndarray, qd: np.ndarray | None = None) -> None:
        """End the task at rest on the path, from the measured ``q`` [rad] on: every later
        :meth:`step` is that of a path-following controller with its rest-to-rest end
        (docs/theory.md §8.9, §8.10) on the same task, robot, period and bounds, started at
        this controller's phase and last commands, which brings the phase velocity to zero
        exactly at ``σ = T_tot``. For a task that ends at speed, called while its end is
        still at least :func:`~dqcontrol.controllers.stop_delegate.end_lead_s` away
        (``run_loop`` does so with ``brake=True``); nothing changes for a controller that
        ends at rest by itself, or one already stopping or finishing.

        With :attr:`end_stream` set (``run_loop`` on the wall clock), the end is that
        streamed controller's, taking over from the measured ``q``, ``qd`` [rad/s]: this
        controller keeps stepping until its first plan starts."""
        if not self._reset_done:
            raise ConfigurationError("call reset(q0) before finish_at_rest()")
        if self.ends_at_rest or self.stopping or self._delegate is not None:
            return
        q = self.robot.check_q(q)
        if self.end_stream is not None:
            self._hand_to_stream(q, qd)
            return
        from dqcontrol.controllers.stop_delegate import stop_delegate

        self._delegate = stop_delegate(self, q, at_end=True)

    def _hand_to_stream(self, q: np.ndarray, qd: np.ndarray | None, stop: bool = False) -> None:
        """:attr:`end_stream` takes over from the measured ``q``, ``qd`` and this
        controller's phase, last command, its acceleration and time scaling (with ``stop``:
        to stop)."""
        end = self.end_stream
        assert end is not None
        before = getattr(self, "qd_before_prev", self.qd_prev)
        a = (self.qd_prev - before) / self.period_s
        end.take_over(q, qd, self.sigma, self.qd_prev.copy(), a, self.s_last, stop)
        self._delegate = end

    @property
    def finishing(self) -> bool:
        """Whether the task's end at rest has been handed over (:meth:`finish_at_rest`)."""
        return self._delegate is not None and not self.stopping

    def _begin_stop(self) -> None:  # noqa: B027 - optional hook
        """Hook of a controller that stops by itself: its next steps brake."""

    @property
    def done(self) -> bool:
        """Whether the phase has reached the end of the task (``σ ≥ T_tot``); after a
        handover to :attr:`end_stream`, whether that stream is done."""
        end = self.end_stream
        if end is not None and self._delegate is end:
            return end.done
        return self.sigma >= self.trajectory.duration - 1e-12

    def step(self, q: np.ndarray, qd: np.ndarray | None = None) -> StepResult:
        """One control step from the measured joint positions ``q`` [rad].

        ``qd`` (measured velocity [rad/s]) is accepted for controllers that use it; the
        acceleration bound is taken relative to the previous *command* (eq. 3.13).
        Raises :class:`ConfigurationError` for a malformed ``q`` (wrong size, NaN/inf) —
        that is a caller bug, not a control situation — but never because a QP failed.
        """
        if not self._reset_done:
            raise ConfigurationError("call reset(q0) before the first step()")
        # the common case checked here (a float array of the right shape, finite: its dot
        # product is); anything else through the model's check and its error messages
        if not (
            type(q) is np.ndarray
            and q.dtype == _FLOAT
            and q.shape == self._q_shape
            and math.isfinite(q.dot(q))
        ):
            q = self.robot.check_q(q)
        if qd is not None:
            qd = self.robot.check_q(qd, "qd")
        if self._delegate is not None or (self.stopping and not self.stops_itself):
            return self._delegated_step(q, qd)
        return self._own_step(q, qd)

    def _own_step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        """This controller's own step from the checked ``q``, ``qd``."""
        if self.measurement_delay_periods and self._sent:
            q = q + self.period_s * np.sum(self._sent, axis=0)
        result = self._step(q, qd)
        self.qd_prev = result.qd_command
        if self.measurement_delay_periods:
            self._sent.append(result.qd_command)
        self.sigma, self.s_last = result.sigma_next, result.s
        return result

    def _delegated_step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        """A step of the delegate (:meth:`request_stop`, :meth:`finish_at_rest`), its phase
        and command kept as this controller's; a streamed end that has no plan started yet
        follows this controller's own step instead."""
        if self._delegate is None and self.end_stream is not None:  # a streamed stop
            self._hand_to_stream(q, qd, stop=True)
        if self._delegate is None:
            from dqcontrol.controllers.stop_delegate import stop_delegate

            self._delegate = stop_delegate(self, q)
        delegate = self._delegate
        if delegate is self.end_stream and delegate.awaits_plan:
            result = self._own_step(q, qd)
            delegate.follow(q, qd, result.qd_command, result.sigma_next)
            return result
        result = delegate.step(q, qd)
        self.qd_before_prev = getattr(delegate, "qd_before_prev", self.qd_prev)
        self.qd_prev = result.qd_command
        self.sigma = result.sigma_next
        return result

    @abstractmethod
    def _step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        """Controller-specific step; ``q`` is already checked."""
