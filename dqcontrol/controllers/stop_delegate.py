"""The path-maintaining stop of a controller without one of its own, and the end at rest
of a task that ends at speed (docs/theory.md §8.10).

The thesis's controllers (and the proportional one) weigh the path against the other goals
in one cost, so asked to brake hard they would trade path accuracy for it. Their stop is
therefore the path-following controller's: one is built on the same robot, (anchored)
task, period and bounds, started at the stopping controller's phase and last command, and
asked to stop; it keeps the path first and brings the phase to rest. Their task ends at
speed (the thesis's convention), and at ``σ = T_tot`` no path is left to brake along: to
end at rest, the last stretch is the path-following controller's rest-to-rest end instead,
handed over once the end is :func:`end_lead_s` away.
"""

from __future__ import annotations

from functools import cache
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.base import Controller
    from dqcontrol.controllers.path_following.controller import PathFollowingController

__all__ = [
    "END_HANDOVER_ERROR_M",
    "END_LEAD_DISTANCES",
    "EndLead",
    "end_lead_s",
    "path_following_like",
    "stop_delegate",
]


def _acceleration_of(controller: Controller) -> np.ndarray | str:
    """The stopping controller's acceleration bound: its constant ``a_max`` [rad/s²], or
    ``"dynamics"`` for a dynamics-aware one."""
    for name in ("a_const", "a_max"):
        value = getattr(controller, name, None)
        if value is not None:
            return np.asarray(value, dtype=float)
    return "dynamics"


def end_lead_s(s: float, qd: np.ndarray, a_max: np.ndarray, jerk_max: np.ndarray) -> float:
    """How far before ``σ = T_tot`` [s of phase] a task that ends at speed hands its end to
    the rest-to-rest path-following controller, moving at time scaling ``s`` with joint
    velocities ``qd`` [rad/s] under ``a_max`` [rad/s²] and ``jerk_max`` [rad/s³]
    (``inf``: none): :class:`EndLead` of the bounds at ``(s, qd)``."""
    return EndLead(a_max, jerk_max, np.shape(qd))(s, qd)


class EndLead:
    """The lead of :func:`end_lead_s` under fixed bounds ``a_max``, ``jerk_max`` (per joint,
    ``shape``), its parts that depend on the bounds only computed once.

    With ``∂q/∂σ ≈ qd/s`` and the phase braking on the rest share ``ρ`` of each joint's
    bound, the phase decelerates at ``b = ρ s min_j a_j/|qd_j|`` and stops within
    ``s²/(2b) = s max_j(|qd_j|/a_j)/(2ρ)``; the rest rows bind from one such distance on
    (§8.9). The lead is :data:`END_LEAD_DISTANCES` of them, plus the phase covered while a
    jerk bound turns the deceleration on and off (``2 s max_j a_j/j_j``).
    """

    def __init__(self, a_max: np.ndarray, jerk_max: np.ndarray, shape: tuple) -> None:
        a = np.broadcast_to(np.asarray(a_max, dtype=float), shape)
        j = np.broadcast_to(np.asarray(jerk_max, dtype=float), shape)
        bounded = np.isfinite(a)  # an unbounded acceleration brakes at once, with no turn
        self._per_speed = np.where(  # [s² / rad]
            bounded, END_LEAD_DISTANCES / (2.0 * _rest_share()) / np.where(bounded, a, 1.0), 0.0
        )
        self._turn = 2.0 * float(np.max(np.where(bounded, a, 0.0) / j))

    def __call__(self, s: float, qd: np.ndarray) -> float:
        """The lead [s of phase] at time scaling ``s`` and joint velocities ``qd``."""
        return s * (float(np.max(np.abs(qd) * self._per_speed)) + self._turn)


#: Braking distances before the end at which a task that ends at speed hands over.
END_LEAD_DISTANCES = 2.0
#: The farthest the tool may be from its target [m] for the handover: a controller farther
#: off is not on the path the end at rest would keep (the path-following controller would
#: first bring the tool back, without progress), and its task ends at speed.
END_HANDOVER_ERROR_M = 0.02


@cache
def _rest_share() -> float:
    """The path-following controller's default share of the bounds its end may brake on."""
    from dqcontrol.controllers.path_following.tuning import PathFollowingTuning

    return PathFollowingTuning().rest_deceleration_share


def path_following_like(
    controller: Controller, period_s: float, at_end: bool
) -> PathFollowingController:
    """A path-following controller on ``controller``'s robot, (anchored) task, velocity and
    acceleration bounds and position margin, of period ``period_s`` [s], with the
    rest-to-rest end (``at_end``) or ending at speed; not reset."""
    from dqcontrol.controllers.path_following.controller import PathFollowingController

    options: dict = {
        "velocity_limits": getattr(controller, "qd_max", None),
        "acceleration_limit": _acceleration_of(controller),
        "end": "rest" if at_end else "at_speed",
    }
    margin = getattr(controller, "position_margin_rad", None)
    if margin is not None:
        options["position_margin_rad"] = margin
    return PathFollowingController(controller.robot, controller.trajectory, period_s, **options)


def stop_delegate(controller: Controller, q: np.ndarray, at_end: bool = False) -> Controller:
    """A path-following controller at ``controller``'s phase and last command and at the
    measured ``q`` [rad]: its stop requested, or (``at_end``) with its rest-to-rest end, to
    finish the task at rest."""
    delegate = path_following_like(controller, controller.period_s, at_end)
    delegate.reset(q, controller.qd_prev.copy(), controller.sigma)
    before = getattr(controller, "qd_before_prev", None)
    if before is not None:  # the acceleration it stops from (its jerk rows read it)
        delegate.qd_before_prev = np.array(before, dtype=float)
    if not at_end:
        delegate.request_stop()
    return delegate
