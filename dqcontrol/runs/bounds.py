"""The hard bounds a controller promised, as a :class:`~dqcontrol.runs.metrics.BoundSpec`."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.base import Controller
from dqcontrol.runs.metrics import BoundSpec

__all__ = ["bounds_of"]


def bounds_of(controller: Controller, q_samples: np.ndarray | None = None) -> BoundSpec:
    """Bounds of ``controller``; for dynamics-aware acceleration limits, the limit at each
    of ``q_samples`` (K, n) is evaluated with the controller's own settings."""
    robot = controller.robot
    qd_max = getattr(controller, "qd_max", robot.limits.qd_max)
    a_const = getattr(controller, "a_const", None)
    if a_const is None:
        a_const = getattr(controller, "a_max", None)
    per_sample = None
    floor = getattr(controller, "acceleration_floor", None)
    cap = getattr(controller, "acceleration_cap", None)
    if (
        a_const is None
        and getattr(controller, "dynamic_acceleration", False)
        and q_samples is not None
        and floor is not None
        and cap is not None
    ):
        per_sample = np.array(
            [robot._acceleration_limits(qi, 1.0, floor, cap) for qi in q_samples]
        ).reshape(len(q_samples), robot.nq)
    return BoundSpec(
        q_min=robot.limits.q_min,
        q_max=robot.limits.q_max,
        qd_max=np.asarray(qd_max, dtype=float),
        a_max=None if a_const is None else np.asarray(a_const, dtype=float),
        a_max_per_sample=per_sample,
    )
