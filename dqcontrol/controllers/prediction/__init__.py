"""Prediction models: how the horizon's states depend on the decision (docs/theory.md §7.2)."""

from dqcontrol.controllers.prediction.base import Prediction, PredictionModel
from dqcontrol.controllers.prediction.consistent import ConsistentPrediction, interval_breakpoints
from dqcontrol.controllers.prediction.matrices import (
    integration_matrix,
    interpolation_matrix,
    prediction_instants,
)
from dqcontrol.controllers.prediction.thesis import ThesisPrediction

__all__ = [
    "ConsistentPrediction",
    "Prediction",
    "PredictionModel",
    "ThesisPrediction",
    "integration_matrix",
    "interpolation_matrix",
    "interval_breakpoints",
    "prediction_instants",
]
