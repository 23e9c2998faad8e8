"""The prediction-model interface (docs/theory.md §7.2)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import NamedTuple

import numpy as np

from dqcontrol.controllers.core.problem import DecisionLayout

__all__ = ["Prediction", "PredictionModel"]


class Prediction(NamedTuple):
    """The states of each block of the horizon as affine functions of the decision.

    ``q_i(z) = q_base[i] + Σ_j weights[i, j] qd_j`` and
    ``σ_i(z) = sigma_base[i] + Σ_j sigma_weights[i, j] s_j`` (``sigma_weights`` ``None``:
    the same as ``weights``); ``q_lin``, ``sigma_lin`` are the points where the kinematics
    are linearised. For the thesis's model the states are data (``weights = 0``,
    ``q_base = q_lin``).
    """

    q_lin: np.ndarray
    sigma_lin: np.ndarray
    q_base: np.ndarray
    sigma_base: np.ndarray
    weights: np.ndarray
    warm_qd: np.ndarray | None
    warm_s: np.ndarray | None
    sigma_weights: np.ndarray | None = None

    @property
    def phase_weights(self) -> np.ndarray:
        """The matrix of ``σ_i(z)`` (``sigma_weights``, or ``weights`` when not given)."""
        return self.weights if self.sigma_weights is None else self.sigma_weights


class PredictionModel(ABC):
    """Memory of the previous plan and the map from it to this step's :class:`Prediction`."""

    layout: DecisionLayout
    #: Whether :meth:`predict` fills ``warm_qd``/``warm_s`` (set by a controller whose
    #: backend warm-starts).
    warm: bool = False

    @abstractmethod
    def reset(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        """Start from rest at ``q0`` (or moving at ``qd0``)."""

    @abstractmethod
    def predict(self, q: np.ndarray, sigma: float) -> Prediction:
        """This step's prediction from the measured ``q`` and phase ``σ``."""

    @abstractmethod
    def commit(self, qd: np.ndarray, s: np.ndarray) -> None:
        """Remember the plan ``qd`` ``(p, n)``, ``s`` ``(p,)`` chosen this step (a copy:
        the caller keeps the arrays it passed)."""
