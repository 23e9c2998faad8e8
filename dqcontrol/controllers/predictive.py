"""The predictive (MPC) method, with and without time scaling (FORMULATION §5.3–5.4)."""

from __future__ import annotations

from dqcontrol.controllers.prediction import prediction_instants
from dqcontrol.controllers.tracking import TrackingController
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = ["PredictiveController", "PredictiveNoScalingController"]


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
    """

    def __init__(
        self, robot: RobotModel, trajectory: Trajectory, period_s: float, **kwargs
    ) -> None:
        kwargs["scaling"] = False
        super().__init__(robot, trajectory, period_s, **kwargs)
        self.name = f"predictive_noscale_p{self.num_instants}"
