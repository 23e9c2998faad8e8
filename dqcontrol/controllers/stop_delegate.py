"""The path-maintaining stop of a controller without one of its own (docs/theory.md §8.10).

The thesis's controllers (and the proportional one) weigh the path against the other goals
in one cost, so asked to brake hard they would trade path accuracy for it. Their stop is
therefore the path-following controller's: one is built on the same robot, (anchored)
task, period and bounds, started at the stopping controller's phase and last command, and
asked to stop; it keeps the path first and brings the phase to rest.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.base import Controller

__all__ = ["stop_delegate"]


def _acceleration_of(controller: Controller) -> np.ndarray | str:
    """The stopping controller's acceleration bound: its constant ``a_max`` [rad/s²], or
    ``"dynamics"`` for a dynamics-aware one."""
    for name in ("a_const", "a_max"):
        value = getattr(controller, name, None)
        if value is not None:
            return np.asarray(value, dtype=float)
    return "dynamics"


def stop_delegate(controller: Controller, q: np.ndarray) -> Controller:
    """A path-following controller at ``controller``'s phase and last command and at the
    measured ``q`` [rad], its stop requested."""
    from dqcontrol.controllers.path_following.controller import PathFollowingController

    options: dict = {
        "velocity_limits": getattr(controller, "qd_max", None),
        "acceleration_limit": _acceleration_of(controller),
        "end": "at_speed",
    }
    margin = getattr(controller, "position_margin_rad", None)
    if margin is not None:
        options["position_margin_rad"] = margin
    delegate = PathFollowingController(
        controller.robot, controller.trajectory, controller.period_s, **options
    )
    delegate.reset(q, controller.qd_prev.copy(), controller.sigma)
    before = getattr(controller, "qd_before_prev", None)
    if before is not None:  # the acceleration it stops from (its jerk rows read it)
        delegate.qd_before_prev = np.array(before, dtype=float)
    delegate.request_stop()
    return delegate
