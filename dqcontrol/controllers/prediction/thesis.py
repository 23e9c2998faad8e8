"""The thesis's prediction: the previous plan shifted by one period and integrated
(docs/theory.md §4.2).

The previous step's commands at the instants ``τ_j`` are taken as a piecewise-linear
function of time, shifted by ``T``, held at its last value past the horizon and integrated
from the measured ``q``: ``q̂ = q + W qd_prev`` with the constant matrix ``W``
(:func:`integration_matrix`); likewise the phase. The states do not depend on this step's
decision.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.prediction.base import Prediction, PredictionModel
from dqcontrol.controllers.prediction.matrices import integration_matrix, interpolation_matrix

__all__ = ["ThesisPrediction"]


class ThesisPrediction(PredictionModel):
    """Predicted ``q̂_i``, ``σ̂_i`` from the previous horizon (data, not decision).

    Args:
        layout: the instants ``τ_i``.
        period_s: control period ``T`` [s].
        phase: ``"previous"`` integrates the previous ``s`` profile; ``"nominal"`` uses
            ``σ + τ_i`` (the thesis); ``"fixed"`` is ``"nominal"`` for ``s ≡ 1``.
        warm: also give the previous plan shifted by one period (``warm_qd``, ``warm_s``:
            a warm start for solvers that take one); ``None`` there otherwise.

    One block (the local method) predicts nothing: the state is the measured one (the same
    :class:`Prediction` object at every step, its arrays refilled).
    """

    def __init__(
        self,
        layout: DecisionLayout,
        period_s: float,
        phase: Literal["previous", "nominal"] = "previous",
        *,
        warm: bool = True,
    ) -> None:
        self.layout = layout
        self.period_s = float(period_s)
        self.phase = phase
        self.warm = bool(warm)
        p, n = layout.num_blocks, layout.num_joints
        tau = layout.instants_s
        self._w_int = integration_matrix(tau, self.period_s) if p > 1 else np.zeros((1, 1))
        self._shift = interpolation_matrix(tau, self.period_s) if p > 1 else np.eye(1)
        self._zero_weights = np.zeros((p, p))
        self.horizon_qd = np.zeros((p, n))
        self.horizon_s = np.ones(p)
        self._q_one, self._sigma_one = np.zeros((1, n)), np.zeros(1)
        self._one = Prediction(
            self._q_one, self._sigma_one, self._q_one, self._sigma_one, self._zero_weights,
            None, None,
        )  # fmt: skip

    def reset(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        """Start with ``qd0`` over the horizon and ``s = 1``."""
        self.horizon_qd = np.tile(qd0, (self.layout.num_blocks, 1))
        self.horizon_s = np.ones(self.layout.num_blocks)

    def predict(self, q: np.ndarray, sigma: float) -> Prediction:
        """The states from the previous plan (data, ``weights = 0``)."""
        if self.layout.num_blocks == 1:  # the same object, its arrays refilled
            self._q_one[0] = q
            self._sigma_one[0] = sigma
            return self._one
        else:
            q_hat = q + self._w_int @ self.horizon_qd
            if self.phase == "previous":
                sigma_hat = sigma + self._w_int @ self.horizon_s
            else:
                sigma_hat = sigma + self.layout.instants_s
        warm_qd: np.ndarray | None = None
        warm_s: np.ndarray | None = None
        if self.warm:
            warm_qd, warm_s = self._shift @ self.horizon_qd, self._shift @ self.horizon_s
        return Prediction(q_hat, sigma_hat, q_hat, sigma_hat, self._zero_weights, warm_qd, warm_s)

    def commit(self, qd: np.ndarray, s: np.ndarray) -> None:
        """Remember the plan ``qd`` ``(p, n)``, ``s`` ``(p,)`` chosen this step."""
        self.horizon_qd = np.array(qd, dtype=float)
        self.horizon_s = np.array(s, dtype=float)
