"""The local method with time scaling (docs/theory.md §4.2, thesis eq. 3.4–3.14, 4.9–4.12)."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.thesis.controller import TrackingController
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = ["LocalController"]


class LocalController(TrackingController):
    """One-block QP: ``min λ1‖J qd - s w‖² + λ2(1-s)² + μ‖qd‖²`` within the hard bounds.

    Decision ``z = [qd; s]``; see
    :class:`~dqcontrol.controllers.thesis.controller.TrackingController` for every keyword
    argument (gain, weights, bounds, solver, priority, extra terms and limits).
    """

    name = "local"

    def __init__(
        self, robot: RobotModel, trajectory: Trajectory, period_s: float, **kwargs
    ) -> None:
        kwargs.pop("instants_s", None)
        super().__init__(robot, trajectory, period_s, instants_s=np.zeros(1), **kwargs)
