"""The predictive (MPC) method, with and without time scaling (docs/theory.md §4.2–4.3)."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.base import check_positive
from dqcontrol.controllers.prediction import integration_matrix, prediction_instants
from dqcontrol.controllers.thesis.controller import TrackingController
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = ["PredictiveController", "PredictiveNoScalingController"]

#: Largest default ``K`` [1/s] of the method without scaling: below the gain at which the
#: applied command falls into a two-period cycle at the acceleration bound
#: (:class:`PredictiveNoScalingController`, docs/theory.md §4.3).
NOSCALE_GAIN_CAP_PER_S = 4.0


class PredictiveController(TrackingController):
    """Receding-horizon QP over ``p`` parabolically spaced instants (eq. 3.15–3.21).

    Args:
        num_instants: ``p ≥ 2`` prediction instants (the thesis used 6 and 10).
        horizon_s: ``τ_p`` [s] (default 1 s, the thesis's ``20 T``).
        **kwargs: see :class:`~dqcontrol.controllers.thesis.controller.TrackingController`
            (``phase_prediction="nominal"`` reproduces the thesis's ``σ(t) + τ_i``).

    Only ``qd_1, s_1`` are applied; the rest of the horizon predicts the next step.
    """

    name = "predictive"

    def __init__(
        self,
        robot: RobotModel,
        trajectory: Trajectory,
        period_s: float,
        *,
        num_instants: int = 10,
        horizon_s: float = 1.0,
        **kwargs,
    ) -> None:
        kwargs.pop("instants_s", None)
        tau = prediction_instants(num_instants, horizon_s)
        super().__init__(robot, trajectory, period_s, instants_s=tau, **kwargs)
        self.num_instants = int(num_instants)
        self.horizon_s = float(horizon_s)
        self.name = f"predictive_p{self.num_instants}"


class PredictiveNoScalingController(PredictiveController):
    """The predictive method with every ``s_i ≡ 1`` (σ = t), thesis §5.4.

    The thesis compared it with ``|qd| ≤ 2 rad/s`` and ``|qdd| ≤ 40 rad/s²``; pass those as
    ``velocity_limits`` / ``acceleration_limit`` to reproduce that comparison.

    Default gain: ``K = min(4, 0.9 / ρ(W))`` [1/s], ``W`` the integration matrix of the
    prediction. A deviation of the predicted horizon is multiplied by about ``K W`` from
    one step to the next; without ``s_i`` to absorb it the horizon diverges unless
    ``K ρ(W) < 1``, and from a lower gain still the applied command falls into a
    two-period cycle at the acceleration bound (docs/theory.md §4.3). Pass ``gain_per_s``
    to choose another.
    """

    def __init__(
        self, robot: RobotModel, trajectory: Trajectory, period_s: float, **kwargs
    ) -> None:
        period_s = check_positive("period_s (T)", period_s, "s")
        if kwargs.get("gain_per_s") is None:
            tau = prediction_instants(kwargs.get("num_instants", 10), kwargs.get("horizon_s", 1.0))
            rho = float(max(abs(np.linalg.eigvals(integration_matrix(tau, period_s)))))
            kwargs["gain_per_s"] = min(NOSCALE_GAIN_CAP_PER_S, 0.9 / rho)
        kwargs["scaling"] = False
        super().__init__(robot, trajectory, period_s, **kwargs)
        self.name = f"predictive_noscale_p{self.num_instants}"
