"""A time-optimal lower bound on the execution time of a Cartesian task.

:func:`time_optimal_bound` answers: along the joint path that follows the task's geometric
path, how fast could the arm go at best, under the same limits as the controllers? The
controllers' execution time divided by this bound measures how close they come to
time-optimal.

The computation has two stages.

1. **Joint path.** The geometric path ``x_d(σ)``, ``σ ∈ [0, T_tot]``, is sampled on a uniform
   grid (its first interval refined, see below) and each sample is solved by inverse
   kinematics, warm-started from the previous one and starting at ``q0``. The 6-D error is
   the pure part of ``e = x* ⊗ x_d`` (``x`` aligned so that ``vec8(x)·vec8(x_d) ≥ 0``):
   ``vec8(e) = H-8(x_d) C8 vec8(x)``, whose pure rows
   ``e6 = [e_1, e_2, e_3, e_5, e_6, e_7]`` are, near the solution, half the rotation vector
   [rad] and half the translation [m] of the error in the tool frame. Newton steps
   ``Δq = -J6ᵀ (J6 J6ᵀ + δ² I)⁻¹ e6`` with ``J6 = rows of H-8(x_d) C8 J`` (δ² = 1e-14, a
   safeguard only) run until ``‖e6‖ ≤ ik_tolerance``, and one more (which takes the
   residual to rounding level). They are least-norm steps, so they do not move the arm
   along its self-motion; the redundancy is resolved by a posture term applied once per
   sample, before the Newton steps::

       q ← q - K_p Δσ N(q) (q - q0),    N = I - J6⁺ J6,

   the explicit Euler step of the self-motion ``dq/dσ = -K_p N (q - q0)``: the posture is
   pulled towards the start configuration ``q0`` (the distance ``‖q - q0‖``) at rate
   ``K_p`` [1/s] in what the path leaves free. This is the redundancy resolution of the
   path-following controller (``PathFollowingController``: its posture level
   ``q̇ = K_p (q0 - q)`` below the path, with the same default ``K_p = 1/s``) at nominal
   speed, ``σ̇ = 1``; running slower, that controller spends more time per unit of path
   and so pulls more per unit of path. With ``K_p = 0`` the joint path is the least-norm
   one (each sample reached by the smallest joint motion from the previous one): the path
   the local and predictive controllers follow when they track exactly, since their
   ``μ ‖q̇‖²`` term picks the least-norm joint velocity among those that follow the task.

2. **Time parameterisation.** A cubic spline ``q(σ)`` through the samples (not-a-knot) is
   parameterised by TOPP-RA (Pham & Pham 2018, package ``toppra``) over the same grid, with
   ``x = σ̇²`` and ``u = σ̈``:

   - joint velocity ``|q'(σ) σ̇| ≤ q̇_max``;
   - joint acceleration ``|q'(σ) u + q''(σ) x| ≤ a_max``, with ``a_max`` constant or, with
     ``"dynamics"``, ``a_max(q) = (τ_max - |g(q)|) / M_jj(q)`` clipped to ``[floor, cap]``
     (:meth:`RobotModel.acceleration_limits`) evaluated at every grid point (a
     ``toppra.constraint.SecondOrderConstraint`` with ``w = q̈``, ``F = [I; -I]``,
     ``g(q) = [a_max(q); a_max(q)]``);
   - optionally joint torque ``|M(q) q̈ + C(q, q̇) q̇ + g(q)| ≤ τ_max`` (Pinocchio's RNEA);
   - the task's nominal speed ``σ̇ ≤ s_max`` (``x ≤ s_max²``): the task never runs faster
     than its nominal timing (``s_max = 1``), as the controllers' time scaling ``s ≤ 1``.

   The motion starts at rest (``σ̇(0) = 0``, as the controllers do) and its end velocity
   is free (the task is done when ``σ`` reaches ``T_tot``; the arm need not stop there), so
   the result is a lower bound on the execution time of any controller that follows this
   joint path within these limits. With ``end_at_rest`` it also ends at rest
   (``σ̇(T) = 0``): the bound of a controller that brings the task to rest at its end.

   The second-order constraints use TOPP-RA's interpolation discretisation: with ``σ̈``
   constant on each grid interval, each constraint holds at both ends of every interval,
   so the profile meets every limit at each grid point and interval end. This is
   conservative by ``O(Δσ)``: the duration converges to the continuous optimum from above,
   at first order (halving ``Δσ`` halves the excess). TOPP-RA is therefore also run on the
   grid with every other point (``2Δσ``), which gives the Richardson estimate
   ``2 D(Δσ) - D(2Δσ)`` of the continuous optimum. The first grid interval is refined
   geometrically so that the start from rest, often shorter than one interval, is resolved.

The bound is time-optimal for this joint path. A redundant arm could follow the same
Cartesian path along another joint path, possibly faster: the bound is a lower bound over
motions along this joint path, not over all joint paths.

``toppra`` is a development dependency, imported only inside :func:`time_optimal_bound`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from dqcontrol.dq.algebra import C8, haminus8
from dqcontrol.errors import ConfigurationError, ParameterError

if TYPE_CHECKING:
    from dqcontrol.model.robot import RobotModel
    from dqcontrol.trajectories.base import Trajectory

__all__ = ["TimeOptimalBound", "TimeOptimalSettings", "time_optimal_bound"]

#: Default number of uniform path samples. On the Table-1 cases ``duration_s`` is then within
#: 7e-4 relative of the continuous optimum and ``duration_extrapolated_s`` within 2e-5
#: (measured against 8001 samples), in about a second.
DEFAULT_SAMPLES = 2001
#: Rows of ``vec8(x* ⊗ x_d)`` that form the 6-D error: the pure parts of both quaternions.
_PURE_ROWS = np.array([1, 2, 3, 5, 6, 7])
#: Damping ``δ²`` of the Newton steps (a safeguard against singular ``J6 J6ᵀ`` only).
_DAMPING = 1e-14
#: Newton iterations per sample before giving up.
_MAX_ITERATIONS = 50
#: Extra grid points in the first interval (geometric, towards σ = 0).
_START_REFINEMENT = 8
#: A limit counts as active where its use is at least this fraction of it.
_ACTIVE_FRACTION = 0.99


@dataclass(frozen=True, eq=False)
class TimeOptimalSettings:
    """The limits and numerical settings a :class:`TimeOptimalBound` was computed with.

    Attributes:
        velocity_limits: ``q̇_max`` per joint [rad/s], shape ``(n,)``.
        acceleration_limit: ``a_max`` per joint [rad/s²], shape ``(n,)``, or ``"dynamics"``
            for ``(τ_max - |g(q)|)/M_jj(q)`` clipped to ``[acceleration_floor,
            acceleration_cap]``.
        acceleration_floor, acceleration_cap: the clipping range of ``"dynamics"`` [rad/s²].
        torque_limits: ``τ_max`` per joint [N·m], shape ``(n,)``, or ``None`` (no torque
            constraint).
        speed_cap: upper bound ``s_max`` on ``σ̇`` (1: the nominal speed).
        posture_gain_per_s: ``K_p`` of the posture term [1/s of nominal time] (0: the
            least-norm path).
        samples: number of uniform path samples (the grid has :data:`_START_REFINEMENT` more
            in its first interval).
        ik_tolerance: bound on ``‖e6‖`` at every sample.
        end_at_rest: the motion ends at rest (``σ̇(T) = 0``), for a controller that brings
            the task to rest at its end; else its end velocity is free.
    """

    velocity_limits: np.ndarray
    acceleration_limit: np.ndarray | str
    acceleration_floor: float
    acceleration_cap: float
    torque_limits: np.ndarray | None
    speed_cap: float
    posture_gain_per_s: float
    samples: int
    ik_tolerance: float
    end_at_rest: bool = False


@dataclass(frozen=True, eq=False)
class TimeOptimalBound:
    """The time-optimal execution of a task along its joint path (:func:`time_optimal_bound`).

    Attributes:
        duration_s: minimum execution time [s]: the time for ``σ`` to go from 0 (at rest)
            to ``T_tot`` within the limits, ``Σ 2 Δσ_i / (σ̇_i + σ̇_{i+1})`` (constant ``σ̈``
            on each grid interval), with the second-order constraints discretised by
            interpolation: the profile meets every limit at each grid point and at both ends
            of each interval. It converges from above, at first order in ``Δσ``.
        duration_coarse_s: the same on the grid with every other point (``2Δσ``).
        nominal_duration_s: the task's nominal duration ``T_tot`` [s].
        samples: number of grid points ``N`` (``settings.samples`` uniform ones and the
            refinement of the first interval).
        ik_max_error: largest ``‖e6‖`` over the samples (pure part of ``x* ⊗ x_d``: about
            half the rotation error [rad] and half the translation error [m]).
        sigma: the grid of ``σ`` [s of nominal time], shape ``(N,)``: uniform on
            ``[0, T_tot]`` with the first interval ``[0, Δ]`` split at ``Δ/2, ..., Δ/2^8``.
        q: joint path [rad] at the grid, shape ``(N, n)``.
        dq_dsigma, d2q_dsigma2: ``q'(σ)`` [rad/s] and ``q''(σ)`` [rad/s²] of the spline
            through ``q``, at the grid, shape ``(N, n)``.
        sigma_dot: time-optimal ``σ̇`` at the grid, shape ``(N,)`` (``σ̇ = 1``: nominal
            speed; ``sigma_dot[0] = 0``: start at rest).
        sigma_ddot: ``σ̈`` [1/s] on each grid interval, shape ``(N-1,)``.
        time_s: time [s] at which ``σ`` reaches each grid point, shape ``(N,)``.
        active_share: for each constraint (``"speed_cap"``, ``"velocity"``,
            ``"acceleration"``, ``"torque"``), the share of ``duration_s`` during which it
            is used to at least 99 % (several can be active at once; time-optimal motion
            has at least one active almost everywhere).
        peak_use: for each constraint, the largest ratio of use to limit on the grid
            (``|q̇_j|/q̇_max_j``, ``|q̈_j|/a_max_j``, ``|τ_j|/τ_max_j``, ``σ̇/s_max``).
        settings: the limits and settings used.
        compute_time_s: wall time of the computation [s].
    """

    duration_s: float
    duration_coarse_s: float
    nominal_duration_s: float
    samples: int
    ik_max_error: float
    sigma: np.ndarray
    q: np.ndarray
    dq_dsigma: np.ndarray
    d2q_dsigma2: np.ndarray
    sigma_dot: np.ndarray
    sigma_ddot: np.ndarray
    time_s: np.ndarray
    active_share: dict[str, float]
    peak_use: dict[str, float]
    settings: TimeOptimalSettings
    compute_time_s: float

    @property
    def ratio(self) -> float:
        """``duration_s / T_tot``: 1 if the task can run at nominal speed throughout."""
        return self.duration_s / self.nominal_duration_s

    @property
    def duration_extrapolated_s(self) -> float:
        """Richardson estimate ``2 D(Δσ) - D(2Δσ)`` [s] of the continuous optimum (the limit
        of ``duration_s`` as ``Δσ → 0``, approached at first order)."""
        return 2.0 * self.duration_s - self.duration_coarse_s

    @property
    def grid_error_s(self) -> float:
        """Estimated excess of ``duration_s`` over the continuous optimum [s]:
        ``D(2Δσ) - D(Δσ)``."""
        return self.duration_coarse_s - self.duration_s

    @property
    def joint_path(self) -> tuple[np.ndarray, np.ndarray]:
        """``(sigma, q)``: the grid ``(N,)`` and the joint path ``(N, n)`` [rad]."""
        return self.sigma, self.q

    def joint_velocities(self) -> np.ndarray:
        """``q̇ = q'(σ) σ̇`` [rad/s] at the grid, shape ``(N, n)``."""
        return self.dq_dsigma * self.sigma_dot[:, None]

    def joint_accelerations(self) -> np.ndarray:
        """``q̈ = q'(σ_i) σ̈_i + q''(σ_i) σ̇_i²`` [rad/s²] at the start of each interval,
        shape ``(N-1, n)``."""
        sd2 = self.sigma_dot[:-1, None] ** 2
        return self.dq_dsigma[:-1] * self.sigma_ddot[:, None] + self.d2q_dsigma2[:-1] * sd2


def time_optimal_bound(
    robot: RobotModel,
    trajectory: Trajectory,
    q0: np.ndarray,
    *,
    velocity_limits: float | np.ndarray,
    acceleration_limit: float | np.ndarray | Literal["dynamics"],
    torque_limits: np.ndarray | Literal["urdf"] | None = None,
    speed_cap: float = 1.0,
    samples: int = DEFAULT_SAMPLES,
    posture_gain_per_s: float = 1.0,
    acceleration_floor: float = 0.5,
    acceleration_cap: float = 50.0,
    ik_tolerance: float = 1e-10,
    end_at_rest: bool = False,
) -> TimeOptimalBound:
    """Minimum execution time of ``trajectory`` from rest at ``q0`` (see the module notes).

    Args:
        robot: the robot model.
        trajectory: the task; without a reference it is anchored at ``robot.pose(q0)``, as
            the controllers do at ``reset``.
        q0: start configuration [rad], shape ``(n,)``; the joint path starts here and the
            posture term pulls towards it.
        velocity_limits: ``q̇_max`` [rad/s], a number or one per joint, finite and ``> 0``.
        acceleration_limit: ``a_max`` [rad/s²], a number or one per joint, finite and
            ``> 0``; or ``"dynamics"``: ``(τ_max - |g(q)|)/M_jj(q)`` clipped to
            ``[acceleration_floor, acceleration_cap]`` at every grid point.
        torque_limits: ``τ_max`` [N·m] per joint, ``"urdf"`` for the URDF's effort limits,
            or ``None`` (no torque constraint).
        speed_cap: ``s_max``, bound on ``σ̇`` (finite, ``> 0``; 1 is the nominal speed).
        samples: number of uniform path samples ``≥ 10`` (the grid of both stages, plus
            the refinement of its first interval).
        posture_gain_per_s: ``K_p ≥ 0`` [1/s] of the posture term (0: least-norm joint
            path; 1/s is the path-following controller's default).
        acceleration_floor: lower end of the clipping range of ``"dynamics"`` [rad/s²].
        acceleration_cap: upper end of the clipping range of ``"dynamics"`` [rad/s²].
        ik_tolerance: bound on ``‖e6‖`` at every sample, in ``(0, 1e-6]``.
        end_at_rest: the motion ends at rest, as the path-following controller's task does
            by default (the bound of a controller that ends at speed has a free end).

    Raises:
        ParameterError: a limit or setting is malformed or out of range (the message names
            it); a sample cannot be reached; the joint path leaves the position limits
            (the message names the joint and ``σ``); TOPP-RA finds no parameterisation.
        ConfigurationError: ``q0`` is malformed, or ``toppra`` is not installed.
    """
    started = time.perf_counter()
    toppra = _import_toppra()
    q0 = robot.check_q(q0, "q0")
    settings = _check_settings(
        robot, velocity_limits=velocity_limits, acceleration_limit=acceleration_limit,
        torque_limits=torque_limits, speed_cap=speed_cap, samples=samples,
        posture_gain_per_s=posture_gain_per_s, acceleration_floor=acceleration_floor,
        acceleration_cap=acceleration_cap, ik_tolerance=ik_tolerance,
        end_at_rest=end_at_rest,
    )  # fmt: skip
    joint_path = _task_joint_path(robot, trajectory, q0, settings)
    return _bound_along(toppra, robot, settings, joint_path, started)


@dataclass(frozen=True, eq=False)
class _JointPath:
    """The joint path of a task (stage 1 of the module notes).

    Attributes:
        nominal_duration_s: the task's nominal duration ``T_tot`` [s].
        sigma: the grid of ``σ`` [s of nominal time], shape ``(N,)`` (:func:`_grid`).
        q: joint path [rad] at the grid, shape ``(N, n)``.
        ik_max_error: largest ``‖e6‖`` over the samples.
    """

    nominal_duration_s: float
    sigma: np.ndarray
    q: np.ndarray
    ik_max_error: float


def _task_joint_path(
    robot: RobotModel, trajectory: Trajectory, q0: np.ndarray, settings: TimeOptimalSettings
) -> _JointPath:
    """The joint path that follows ``trajectory`` from ``q0``, within the position limits.

    A trajectory without a reference is first anchored at ``robot.pose(q0)``.

    Raises:
        ParameterError: a sample cannot be reached, or the path leaves the position limits.
    """
    if trajectory.reference is None:
        trajectory = trajectory.anchored_at(robot.pose(q0))
    duration = trajectory.duration
    sigma = _grid(duration, settings.samples, settings.end_at_rest)
    targets, _ = trajectory.targets(sigma)
    q, ik_error = _joint_path(robot, targets, sigma, q0, settings)
    _check_position_limits(robot, sigma, q)
    return _JointPath(duration, sigma, q, ik_error)


def _bound_along(
    toppra: Any,
    robot: RobotModel,
    settings: TimeOptimalSettings,
    joint_path: _JointPath,
    started: float,
) -> TimeOptimalBound:
    """The time-optimal parameterisation of ``joint_path`` (stage 2 of the module notes).

    Args:
        toppra: the ``toppra`` module.
        robot: the robot model.
        settings: the checked limits and settings.
        joint_path: the joint path of the task.
        started: :func:`time.perf_counter` at the start of the computation.

    Raises:
        ParameterError: TOPP-RA finds no parameterisation of the path, on either grid.
    """
    sigma, q = joint_path.sigma, joint_path.q
    path = toppra.SplineInterpolator(sigma, q)
    dq = np.asarray(path(sigma, 1)).reshape(-1, robot.nq)
    ddq = np.asarray(path(sigma, 2)).reshape(-1, robot.nq)
    a_max = _AccelerationTable(robot, settings)
    constraints = _constraints(toppra, robot, settings, a_max)
    end = settings.end_at_rest
    sd = _parameterize(toppra, path, sigma, constraints, end)
    duration_coarse = _coarse_duration(toppra, sigma, q, constraints, end)
    sdd, dt, times = _interval_timing(sigma, sd)
    share, peak = _constraint_use(robot, settings, a_max, q, dq, ddq, sd, sdd, dt)
    return TimeOptimalBound(
        duration_s=float(times[-1]),
        duration_coarse_s=duration_coarse,
        nominal_duration_s=float(joint_path.nominal_duration_s),
        samples=int(sigma.size),
        ik_max_error=float(joint_path.ik_max_error),
        sigma=sigma,
        q=q,
        dq_dsigma=dq,
        d2q_dsigma2=ddq,
        sigma_dot=sd,
        sigma_ddot=sdd,
        time_s=times,
        active_share=share,
        peak_use=peak,
        settings=settings,
        compute_time_s=time.perf_counter() - started,
    )


def _coarse_duration(
    toppra: Any, sigma: np.ndarray, q: np.ndarray, constraints: list[Any], end_at_rest: bool
) -> float:
    """The time-optimal duration [s] on the grid with every other point (``2Δσ``).

    Raises:
        ParameterError: TOPP-RA finds no parameterisation on that grid.
    """
    coarse = _coarse_indices(sigma.size, end_at_rest)
    coarse_path = toppra.SplineInterpolator(sigma[coarse], q[coarse])
    sd_coarse = _parameterize(toppra, coarse_path, sigma[coarse], constraints, end_at_rest)
    delta_coarse = np.diff(sigma[coarse])
    return float(np.sum(2.0 * delta_coarse / (sd_coarse[:-1] + sd_coarse[1:])))


def _interval_timing(
    sigma: np.ndarray, sd: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``σ̈`` [1/s] and the duration [s] of each grid interval, and the time [s] at each
    grid point, for ``σ̇ = sd`` at the grid and ``σ̈`` constant on each interval.

    With ``x = σ̇²``: ``x_{i+1} = x_i + 2 Δσ u_i`` and ``Δt = 2 Δσ / (σ̇_i + σ̇_{i+1})``.
    """
    delta = np.diff(sigma)
    sdd = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * delta)
    dt = 2.0 * delta / (sd[:-1] + sd[1:])
    times = np.concatenate(([0.0], np.cumsum(dt)))
    return sdd, dt, times


# ---------------------------------------------------------------------------- checks
def _import_toppra() -> Any:
    """The ``toppra`` module, or :class:`ConfigurationError` saying how to install it."""
    try:
        import toppra
    except ImportError as exc:
        raise ConfigurationError(
            f"the time-optimal bound needs toppra ({exc}); install it with "
            "'pip install toppra' or the development extra 'pip install -e \".[dev]\"'"
        ) from None
    return toppra


def _positive_vector(name: str, value: Any, n: int, unit: str) -> np.ndarray:
    """``value`` (a number or ``n`` numbers) as a finite, positive ``(n,)`` array."""
    if isinstance(value, str | bool):
        raise ParameterError(f"{name} must be a number or {n} numbers > 0 [{unit}], got {value!r}")
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(
            f"{name} must be a number or {n} numbers > 0 [{unit}], got {value!r}"
        ) from None
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ParameterError(
            f"{name} must be a number or an array of shape ({n},) [{unit}], got shape {arr.shape}"
        )
    if not (np.all(np.isfinite(arr)) and np.all(arr > 0.0)):
        raise ParameterError(f"{name} must be finite and > 0 [{unit}], got {arr}")
    return arr


def _positive_number(name: str, value: Any, unit: str, *, allow_zero: bool = False) -> float:
    """``value`` as a finite float ``> 0`` (or ``≥ 0``)."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ParameterError(f"{name} must be a number [{unit}], got {value!r}")
    number = float(value)
    if not math.isfinite(number) or number < 0.0 or (number == 0.0 and not allow_zero):
        bound = "≥ 0" if allow_zero else "> 0"
        raise ParameterError(f"{name} must be finite and {bound} [{unit}], got {value!r}")
    return number


def _check_settings(robot: RobotModel, **kw: Any) -> TimeOptimalSettings:
    """The checked, normalised :class:`TimeOptimalSettings` of the keyword arguments."""
    n = robot.nq
    velocity = _positive_vector("velocity_limits", kw["velocity_limits"], n, "rad/s")
    floor = _positive_number("acceleration_floor", kw["acceleration_floor"], "rad/s²")
    cap = _positive_number("acceleration_cap", kw["acceleration_cap"], "rad/s²")
    acceleration: np.ndarray | str
    if isinstance(kw["acceleration_limit"], str):
        if kw["acceleration_limit"] != "dynamics":
            raise ParameterError(
                "acceleration_limit must be a number, one number per joint [rad/s²] or "
                f"'dynamics', got {kw['acceleration_limit']!r}"
            )
        if floor > cap:
            raise ParameterError(
                f"need acceleration_floor ≤ acceleration_cap [rad/s²], got {floor} and {cap}"
            )
        acceleration = "dynamics"
    else:
        acceleration = _positive_vector("acceleration_limit", kw["acceleration_limit"], n, "rad/s²")
    torque = kw["torque_limits"]
    if isinstance(torque, str):
        if torque != "urdf":
            raise ParameterError(
                f"torque_limits must be None, 'urdf' or {n} numbers > 0 [N·m], got {torque!r}"
            )
        torque = _positive_vector(
            "torque_limits (the URDF's effort limits)", robot.limits.effort_max, n, "N·m"
        )
    elif torque is not None:
        torque = _positive_vector("torque_limits", torque, n, "N·m")
    samples = kw["samples"]
    if isinstance(samples, bool) or not isinstance(samples, int | np.integer) or samples < 10:
        raise ParameterError(f"samples must be an integer ≥ 10, got {samples!r}")
    tolerance = _positive_number("ik_tolerance", kw["ik_tolerance"], "1")
    if tolerance > 1e-6:
        raise ParameterError(f"ik_tolerance must be in (0, 1e-6], got {tolerance!r}")
    return TimeOptimalSettings(
        velocity_limits=velocity,
        acceleration_limit=acceleration,
        acceleration_floor=floor,
        acceleration_cap=cap,
        torque_limits=torque,
        speed_cap=_positive_number("speed_cap", kw["speed_cap"], "1"),
        posture_gain_per_s=_positive_number(
            "posture_gain_per_s", kw["posture_gain_per_s"], "1/s", allow_zero=True
        ),
        samples=int(samples),
        ik_tolerance=tolerance,
        end_at_rest=bool(kw["end_at_rest"]),
    )


# ---------------------------------------------------------------------------- joint path
def _grid(duration: float, samples: int, end_at_rest: bool = False) -> np.ndarray:
    """``samples`` points evenly spaced on ``[0, T_tot]``, the first interval ``[0, Δ]`` split
    further at ``Δ/2, Δ/4, ..., Δ/2^k`` (:data:`_START_REFINEMENT` points) to resolve the
    start from rest; with ``end_at_rest`` the last interval likewise, mirrored, to resolve
    the end at rest."""
    uniform = np.linspace(0.0, duration, samples)
    start = uniform[1] * 0.5 ** np.arange(_START_REFINEMENT, 0, -1)
    grid = np.concatenate(([0.0], start, uniform[1:]))
    if not end_at_rest:
        return grid
    end = duration - start[::-1]
    return np.concatenate((grid[:-1], end, [duration]))


def _joint_path(
    robot: RobotModel,
    targets: np.ndarray,
    sigma: np.ndarray,
    q0: np.ndarray,
    settings: TimeOptimalSettings,
) -> tuple[np.ndarray, float]:
    """Inverse kinematics of every target, warm-started, with the posture step (module notes).

    Returns the joint path ``(N, n)`` and the largest final ``‖e6‖``.
    """
    n = robot.nq
    eye = np.eye(n)
    damping = _DAMPING * np.eye(6)
    tol = settings.ik_tolerance
    gain = settings.posture_gain_per_s
    q = q0.copy()
    out = np.empty((targets.shape[0], n))
    worst = 0.0
    j6 = None
    for i, x_d in enumerate(targets):
        # P x = pure rows of vec8(x* ⊗ x_d) = H-8(x_d) C8 vec8(x)
        proj = (haminus8(x_d) @ C8)[_PURE_ROWS]
        if i > 0 and gain > 0.0 and j6 is not None:
            null = eye - j6.T @ np.linalg.solve(j6 @ j6.T + damping, j6)
            q = q - (gain * (sigma[i] - sigma[i - 1])) * (null @ (q - q0))
        converged: tuple[np.ndarray, float] | None = None
        for iteration in range(_MAX_ITERATIONS + 2):
            x, jac = robot.pose_and_jacobian(q)
            if x.dot(x_d) < 0.0:
                x, jac = -x, -jac
            e6 = proj @ x
            j6 = proj @ jac
            err = float(np.sqrt(e6.dot(e6)))
            if converged is not None:  # the extra step is done: keep the better of the two
                if not err <= converged[1]:
                    q, err = converged
                break
            if err <= tol:
                # one Newton step more takes the residual to rounding level (~1e-15), which
                # keeps it out of the spline's q'' on the short first intervals
                converged = (q, err)
            elif iteration >= _MAX_ITERATIONS or not math.isfinite(err):
                raise ParameterError(
                    f"inverse kinematics did not reach the target at sample {i} "
                    f"(σ = {sigma[i]:.6g} s) within {_MAX_ITERATIONS} Newton steps: "
                    f"‖e6‖ = {err:.3g} > {tol:g}; the path leaves the workspace or passes "
                    "through a singularity"
                )
            q = q - j6.T @ np.linalg.solve(j6 @ j6.T + damping, e6)
        out[i] = q
        worst = max(worst, err)
    return out, worst


def _check_position_limits(robot: RobotModel, sigma: np.ndarray, q: np.ndarray) -> None:
    """:class:`ParameterError` naming the first joint and ``σ`` where ``q`` leaves its limits."""
    lo, hi = robot.limits.q_min, robot.limits.q_max
    outside = (q < lo) | (q > hi)
    if not outside.any():
        return
    i, j = (int(v) for v in np.argwhere(outside)[0])
    side, limit = ("below", lo[j]) if q[i, j] < lo[j] else ("above", hi[j])
    raise ParameterError(
        f"the joint path leaves the position limits: joint '{robot.joint_names[j]}' reaches "
        f"{q[i, j]:.4f} rad at σ = {sigma[i]:.4g} s, {side} its limit {limit:.4f} rad "
        f"(limits [{lo[j]:.4f}, {hi[j]:.4f}] rad); choose another q0 or posture_gain_per_s"
    )


# ---------------------------------------------------------------------------- TOPP-RA
def _constraints(
    toppra: Any, robot: RobotModel, settings: TimeOptimalSettings, a_max: _AccelerationTable
) -> list[Any]:
    """The TOPP-RA constraint objects of ``settings`` (module notes, stage 2)."""
    import pinocchio as pin

    constraint = toppra.constraint
    interpolation = constraint.DiscretizationType.Interpolation
    n = robot.nq
    out = [
        constraint.JointVelocityConstraint(settings.velocity_limits),
        _speed_cap_constraint(toppra, settings.speed_cap, n),
    ]
    if isinstance(settings.acceleration_limit, str):
        stacked = np.vstack((np.eye(n), -np.eye(n)))

        def bound(q: np.ndarray) -> np.ndarray:
            limit = a_max(q)
            return np.concatenate((limit, limit))

        # w = q̈ = q' σ̈ + q'' σ̇², F w ≤ g: -a_max(q) ≤ q̈ ≤ a_max(q)
        out.append(
            constraint.SecondOrderConstraint(
                lambda q, qd, qdd: np.array(qdd, dtype=float),
                lambda q: stacked,
                bound,
                n,
                discretization_scheme=interpolation,
            )
        )
    else:
        out.append(
            constraint.JointAccelerationConstraint(
                settings.acceleration_limit, discretization_scheme=interpolation
            )
        )
    if settings.torque_limits is not None:
        model, data = robot.model, robot.model.createData()

        def inverse_dynamics(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
            return np.array(pin.rnea(model, data, q, qd, qdd))  # a copy: rnea returns data.tau

        tau = settings.torque_limits
        out.append(
            constraint.JointTorqueConstraint(
                inverse_dynamics,
                np.column_stack((-tau, tau)),
                np.zeros(n),
                discretization_scheme=interpolation,
            )
        )
    return out


def _parameterize(
    toppra: Any, path: Any, sigma: np.ndarray, constraints: list[Any], end_at_rest: bool
) -> np.ndarray:
    """Time-optimal ``σ̇`` at the grid ``sigma`` from rest, to rest (``end_at_rest``) or with
    a free end."""
    kind = toppra.algorithm.TOPPRA if end_at_rest else _free_end_toppra(toppra)
    algorithm = kind(constraints, path, gridpoints=sigma)
    _, sd, _ = algorithm.compute_parameterization(0.0, 0.0)
    if sd is None or not np.all(np.isfinite(sd)):
        raise ParameterError(
            "TOPP-RA found no time parameterisation of the joint path "
            f"({algorithm.problem_data.return_code}): the limits admit no motion along it"
        )
    sd = np.maximum(np.asarray(sd, dtype=float), 0.0)
    sd[0] = 0.0
    stuck = np.flatnonzero(sd[:-1] + sd[1:] <= 0.0)
    if stuck.size:
        raise ParameterError(
            f"the joint path cannot be traversed: σ̇ = 0 on [{sigma[stuck[0]]:.6g}, "
            f"{sigma[stuck[0] + 1]:.6g}] s (a limit admits no motion there)"
        )
    return sd


def _coarse_indices(size: int, end_at_rest: bool = False) -> np.ndarray:
    """Indices of the :func:`_grid` points that form the same grid with twice the spacing:
    ``0``, the refinement ``2Δ/2^k = Δ/2^(k-1)``, ``Δ``, then every other uniform point
    (and the last one); with ``end_at_rest`` the end's refinement mirrored."""
    if end_at_rest:  # the start's refinement, then every other point, then the end's
        first, last = 1 + _START_REFINEMENT, size - 2 - _START_REFINEMENT  # σ = Δ, T - Δ
        start = np.concatenate(([0], np.arange(2, first + 1)))
        middle = np.arange(first, last + 1, 2)
        return np.unique(np.concatenate((start, middle, [last], size - 1 - start[::-1])))
    first_uniform = 1 + _START_REFINEMENT  # index of σ = Δ
    uniform = np.arange(first_uniform, size)
    keep = uniform[(uniform - first_uniform) % 2 == 1]  # 2Δ, 4Δ, ...
    if keep.size == 0 or keep[-1] != size - 1:
        keep = np.append(keep, size - 1)
    return np.concatenate(([0], np.arange(2, first_uniform + 1), keep))


class _AccelerationTable:
    """``a_max(q)`` [rad/s²] per joint: the constant limit, or the ``"dynamics"`` limit
    (:meth:`RobotModel.acceleration_limits`) memoised per configuration."""

    def __init__(self, robot: RobotModel, settings: TimeOptimalSettings) -> None:
        self._robot = robot
        self._constant = (
            None if isinstance(settings.acceleration_limit, str) else settings.acceleration_limit
        )
        self._floor = settings.acceleration_floor
        self._cap = settings.acceleration_cap
        self._memo: dict[bytes, np.ndarray] = {}

    def __call__(self, q: np.ndarray) -> np.ndarray:
        if self._constant is not None:
            return self._constant
        q = np.ascontiguousarray(q, dtype=float)
        key = q.tobytes()
        limit = self._memo.get(key)
        if limit is None:
            limit = self._robot.acceleration_limits(
                q, floor_rad_s2=self._floor, cap_rad_s2=self._cap
            )
            self._memo[key] = limit
        return limit


def _speed_cap_constraint(toppra: Any, cap: float, dof: int) -> Any:
    """A first-order TOPP-RA constraint ``σ̇ ≤ cap``: ``x = σ̇² ∈ [0, cap²]`` at every point."""

    class PathSpeedCap(toppra.constraint.LinearConstraint):
        """``σ̇ ≤ s_max`` on the path parameter (``x ≤ s_max²``)."""

        def __init__(self) -> None:
            super().__init__()
            self.dof = dof
            self._format_string = f"    Path speed cap: {cap}\n"

        def compute_constraint_params(self, path: Any, gridpoints: np.ndarray) -> tuple:
            xbound = np.zeros((len(gridpoints), 2))
            xbound[:, 1] = cap * cap
            return None, None, None, None, None, None, xbound

    return PathSpeedCap()


def _free_end_toppra(toppra: Any) -> type:
    """TOPP-RA with a free end velocity: the controllable set at the last grid point is its
    whole feasible set ``[0, x_max]`` instead of one given velocity."""

    class FreeEndTOPPRA(toppra.algorithm.TOPPRA):
        """:class:`toppra.algorithm.TOPPRA` whose end velocity is free (its requested
        ``sd_end`` is ignored)."""

        def compute_controllable_sets(self, sdmin: float, sdmax: float) -> np.ndarray:
            wrapper = self.solver_wrapper
            g = np.zeros(wrapper.get_no_vars())
            g[1] = -1.0  # maximise x at the last grid point
            big = 1e8
            wrapper.setup_solver()
            x_max = wrapper.solve_stagewise_optim(self._N, None, g, 0.0, big, -big, big)[1]
            wrapper.close_solver()
            if not (math.isfinite(x_max) and x_max >= 0.0):
                x_max = 0.0
            return super().compute_controllable_sets(0.0, math.sqrt(x_max))

    return FreeEndTOPPRA


def _constraint_use(
    robot: RobotModel,
    settings: TimeOptimalSettings,
    a_max: _AccelerationTable,
    q: np.ndarray,
    dq: np.ndarray,
    ddq: np.ndarray,
    sd: np.ndarray,
    sdd: np.ndarray,
    dt: np.ndarray,
) -> tuple[dict[str, float], dict[str, float]]:
    """Share of the time each constraint is active, and its peak use (see the fields)."""
    import pinocchio as pin

    qd = dq * sd[:, None]
    # acceleration at both ends of each interval (σ̈ constant on it)
    qdd_start = dq[:-1] * sdd[:, None] + ddq[:-1] * (sd[:-1, None] ** 2)
    qdd_end = dq[1:] * sdd[:, None] + ddq[1:] * (sd[1:, None] ** 2)
    use: dict[str, np.ndarray] = {
        "speed_cap": np.maximum(sd[:-1], sd[1:]) / settings.speed_cap,
        "velocity": np.maximum(
            np.max(np.abs(qd[:-1]) / settings.velocity_limits, axis=1),
            np.max(np.abs(qd[1:]) / settings.velocity_limits, axis=1),
        ),
    }
    limits = np.array([a_max(qi) for qi in q])
    a_start, a_end = limits[:-1], limits[1:]
    use["acceleration"] = np.maximum(
        np.max(np.abs(qdd_start) / a_start, axis=1), np.max(np.abs(qdd_end) / a_end, axis=1)
    )
    if settings.torque_limits is not None:
        model, data = robot.model, robot.model.createData()
        tau = settings.torque_limits
        ratio = np.empty(len(dt))
        for i in range(len(dt)):
            t0 = np.abs(pin.rnea(model, data, q[i], qd[i], qdd_start[i])) / tau
            t1 = np.abs(pin.rnea(model, data, q[i + 1], qd[i + 1], qdd_end[i])) / tau
            ratio[i] = max(float(t0.max()), float(t1.max()))
        use["torque"] = ratio
    total = float(dt.sum())
    share = {k: float(dt[v >= _ACTIVE_FRACTION].sum() / total) for k, v in use.items()}
    peak = {k: float(v.max()) for k, v in use.items()}
    return share, peak
