"""The predictive (MPC) method, with and without time scaling (FORMULATION §5.3–5.4)."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.base import check_positive
from dqcontrol.controllers.prediction import integration_matrix, prediction_instants
from dqcontrol.controllers.tracking import TrackingController
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = ["PredictiveController", "PredictiveNoScalingController"]

#: Largest default ``K`` [1/s] of the method without scaling: below the two-period cycle
#: measured from 4.6 s⁻¹ (:class:`PredictiveNoScalingController`).
NOSCALE_GAIN_CAP_PER_S = 4.0


class PredictiveController(TrackingController):
    """Receding-horizon QP over ``p`` parabolically spaced instants (eq. 3.15–3.21).

    Args:
        num_instants: ``p ≥ 2`` prediction instants (the thesis used 6 and 10).
        horizon_s: ``τ_p`` [s] (default 1 s, the thesis's ``20 T``).
        **kwargs: see :class:`~dqcontrol.controllers.tracking.TrackingController`
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

    Default gain. The predicted poses ``x̂_i`` come from integrating the previous horizon
    (``q̂ = q + W qd_prev``), and each ``qd_i`` answers the predicted error with gain ``K``;
    from one step to the next, a deviation of the horizon is therefore multiplied by about
    ``K W``. Without ``s_i`` to absorb it (the scaled method shrinks ``s_i`` instead), the
    horizon diverges unless ``K ρ(W) < 1``; we measured divergence from ``K ρ(W) ≈ 1.2``
    (p = 6 and 10, τ_p = 1 s, T = 50 ms). A second limit comes first: the applied command
    falls into a two-period cycle at the acceleration bound (``qd`` alternating by
    ``T a_max`` every step, the QP re-choosing ~35 active constraints each time) from ``K``
    between 4.6 and 9.5 s⁻¹ (measured onsets on the LBR4p: circle, p = 6 and 10,
    T = 1–50 ms, τ_p = 0.5–2 s: 5.1–9.5; the sinusoid at T = 50 ms: 4.6–5), where
    ``0.9 / ρ(W)`` would allow 8.5 (p = 10, T = 1 ms) and 17 (τ_p = 0.5 s). The default
    is therefore ``K = min(4, 0.9 / ρ(W))`` [1/s] (3.6 for p = 6 at T = 50 ms, 4 for
    p = 10 and at 1 ms). Pass ``gain_per_s`` to choose another.
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
