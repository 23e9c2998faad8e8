"""The numbers that define the thesis's experiment, in one place.

The KUKA LBR4p from :data:`~dqcontrol.model.library.LBR4P_Q0`, sampled every ``T = 0.05 s``,
a prediction horizon ``τ_p = 1 s``, the joint-velocity bounds ``π·[1,1,1,1,2.5,2.5,2.5]``
rad/s (thesis eq. 4.13) and a constant joint-acceleration bound of 10 rad/s². Table 1, the
fault campaign, ``dqcontrol run`` and the benchmark read them from here. The URDF carries the
hardware's own limits; these are passed explicitly wherever the thesis's experiment is run.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol.model.library import LBR4P_Q0

__all__ = [
    "THESIS_ACCELERATION_LIMIT",
    "THESIS_HORIZON_S",
    "THESIS_PERIOD_S",
    "THESIS_Q0",
    "THESIS_VELOCITY_LIMITS",
    "thesis_bounds",
]

#: Joint-velocity bounds ``q̇_max`` (thesis eq. 4.13) [rad/s].
THESIS_VELOCITY_LIMITS: tuple[float, ...] = tuple(
    math.pi * v for v in (1.0, 1.0, 1.0, 1.0, 2.5, 2.5, 2.5)
)
#: Constant joint-acceleration bound ``a_max`` [rad/s²].
THESIS_ACCELERATION_LIMIT = 10.0
#: Control period ``T`` [s].
THESIS_PERIOD_S = 0.05
#: Prediction horizon ``τ_p`` [s].
THESIS_HORIZON_S = 1.0
#: Start configuration [rad] (the model library's array: copy it before changing it).
THESIS_Q0: np.ndarray = LBR4P_Q0


def thesis_bounds() -> dict[str, object]:
    """``{"velocity_limits": q̇_max [rad/s], "acceleration_limit": a_max [rad/s²]}``, fresh
    objects for a controller's keyword arguments."""
    return {
        "velocity_limits": np.array(THESIS_VELOCITY_LIMITS),
        "acceleration_limit": THESIS_ACCELERATION_LIMIT,
    }
