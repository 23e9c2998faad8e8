"""The tuning of the path-following controller: tolerances, linearisation, trust region
(docs/theory.md §8). The defaults are the measured choices of §8; a user rarely needs
another."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dqcontrol.controllers.base import check_positive
from dqcontrol.errors import ParameterError

__all__ = [
    "GROWTH_PARABOLIC",
    "RESERVE_REPLANNED_ONCE",
    "RESERVE_REPLANNED_OFTEN",
    "PathFollowingTuning",
]

#: Default growth of the horizon's intervals: parabolic (``Δ_1 = (τ_p - T)/(p - 1)²``).
GROWTH_PARABOLIC = 2.0

#: Default share of ``a_max`` between intervals where the loop re-plans at most once within
#: the plan's second interval: the reserve absorbs the linearisation's error.
RESERVE_REPLANNED_ONCE = 0.9
#: The same where the loop re-plans several times within the plan's second interval: the
#: applied command then ramps, a period at a time, towards a velocity the plan reaches at
#: once, and behind a velocity servo it must also lead the joint (docs/theory.md §8.4).
RESERVE_REPLANNED_OFTEN = 0.6


@dataclass(frozen=True)
class PathFollowingTuning:
    """Expert settings of the path-following controller
    (:class:`~dqcontrol.controllers.path_following.controller.PathFollowingController`).

    Attributes:
        path_tolerance: how far lower levels may move each path-error row from its optimum
            where a level falls back to bands (half-radians / half-metres, > 0); otherwise
            they hold it exactly (docs/theory.md §7.4).
        progress_tolerance: the same for the progress rows (> 0).
        damping: the regularisation weight of every level (> 0).
        max_linearisations: bound on linearise-and-solve rounds per step (integer ≥ 1).
        linearisation_tolerance: where the linearisation point is poor (first step, after a
            fallback or a disturbance), the rounds stop when the plan moves less than this
            [rad/s].
        linearisation_tolerance_m: otherwise, a round is added while the linearised path
            error of the applied state is further than this from the true one (tangent
            units, about half a metre or half a radian per unit).
        relinearise_threshold_rad: a measured ``q`` this far from the predicted one counts as
            a disturbance [rad].
        acceleration_reserve: share of ``a_max`` the plan may use between intervals, in
            ``(0, 1]`` (the applied command may use all of it); ``None`` (default): by the
            loop's period (:meth:`reserve_for`).
        trust_radius_rad: ``ρ_q``, the trust region of the joint states now [rad]; it grows
            as ``1 + t/t_g`` with the state's time ``t``.
        trust_radius_phase_s: ``ρ_σ``, the same for the phase [s].
        trust_growth_time_s: ``t_g`` [s].
        path_full_weight_time_s: the path errors of the states up to this time from now
            weigh fully, later ones less as ``(t_w/t)²`` [s] (docs/theory.md §8.2).
        position_slack_rad: when the predicted position rows leave no feasible plan, they
            are tried this much looser [rad] before they are dropped (docs/theory.md §8.6);
            keep it below the controller's position margin.
        rest_deceleration_share: share of each joint's acceleration bound the braking of
            the phase at the task's end may use, in ``(0, 1]`` (docs/theory.md §8.9).
        interval_growth: the power ``g ≥ 1`` the horizon's intervals grow by
            (:func:`~dqcontrol.controllers.prediction.consistent.interval_breakpoints`);
            ``None`` (default): parabolic, or under a jerk bound as :meth:`growth_for`
            says (docs/theory.md §8.11).
    """

    path_tolerance: float = 1e-6
    progress_tolerance: float = 1e-6
    damping: float = 1e-6
    max_linearisations: int = 4
    linearisation_tolerance: float = 1e-4
    linearisation_tolerance_m: float = 1e-5
    relinearise_threshold_rad: float = 0.02
    acceleration_reserve: float | None = None
    trust_radius_rad: float = 0.05
    trust_radius_phase_s: float = 0.02
    trust_growth_time_s: float = 0.05
    path_full_weight_time_s: float = 0.05
    position_slack_rad: float = 1e-3
    rest_deceleration_share: float = 0.5
    interval_growth: float | None = None

    def __post_init__(self) -> None:
        units = {
            "path_tolerance": "-", "progress_tolerance": "-", "damping": "-",
            "linearisation_tolerance": "rad/s", "linearisation_tolerance_m": "m",
            "relinearise_threshold_rad": "rad",
            "trust_radius_rad": "rad", "trust_radius_phase_s": "s", "trust_growth_time_s": "s",
            "path_full_weight_time_s": "s", "position_slack_rad": "rad",
            "rest_deceleration_share": "-",
        }  # fmt: skip
        for name, unit in units.items():
            object.__setattr__(self, name, check_positive(name, getattr(self, name), unit))
        if self.rest_deceleration_share > 1.0:
            raise ParameterError(
                f"rest_deceleration_share must be in (0, 1], got {self.rest_deceleration_share!r}"
            )
        reserve = self.acceleration_reserve
        if reserve is not None:
            reserve = check_positive("acceleration_reserve", reserve, "-")
            if reserve > 1.0:
                raise ParameterError(f"acceleration_reserve must be in (0, 1], got {reserve!r}")
            object.__setattr__(self, "acceleration_reserve", reserve)
        growth = self.interval_growth
        number = isinstance(growth, int | float) and not isinstance(growth, bool)
        if growth is not None and not (number and np.isfinite(growth) and growth >= 1.0):
            raise ParameterError(f"interval_growth must be finite and ≥ 1, got {growth!r}")
        rounds = self.max_linearisations
        if isinstance(rounds, bool) or int(rounds) != rounds or rounds < 1:
            raise ParameterError(f"max_linearisations must be an integer ≥ 1, got {rounds!r}")
        object.__setattr__(self, "max_linearisations", int(rounds))

    def growth_for(
        self, horizon_s: float, period_s: float, num_intervals: int, turn_s: float | None
    ) -> float:
        """The intervals' growth: the one given; else :data:`GROWTH_PARABOLIC`, or, where a
        joint's acceleration takes ``turn_s`` [s] to turn round under a jerk bound
        (``2 ā/j̄``), the least growth ``≥ 2`` whose second interval
        ``(τ_p - T)/(p - 1)^g`` is no longer than that (docs/theory.md §8.11)."""
        if self.interval_growth is not None:
            return float(self.interval_growth)
        p = num_intervals if isinstance(num_intervals, int | float) else 0  # checked later
        if turn_s is None or p < 3 or horizon_s - period_s <= turn_s:
            return GROWTH_PARABOLIC
        needed = np.log((horizon_s - period_s) / turn_s) / np.log(p - 1.0)
        return max(GROWTH_PARABOLIC, float(needed))

    def reserve_for(self, period_s: float, second_interval_s: float) -> float:
        """The share of ``a_max`` the coupling rows allow: the one given, or by default
        :data:`RESERVE_REPLANNED_OFTEN` where the loop re-plans at least twice within the
        plan's second interval (``Δ_1 ≥ 2 T``) and :data:`RESERVE_REPLANNED_ONCE` otherwise
        (docs/theory.md §8.4)."""
        if self.acceleration_reserve is not None:
            return self.acceleration_reserve
        if second_interval_s >= 2.0 * period_s:
            return RESERVE_REPLANNED_OFTEN
        return RESERVE_REPLANNED_ONCE
