"""The thesis's QP controllers with time scaling (docs/theory.md §4.2, §7.6): the tracking
composition on the QP core, the local method (one block) and the predictive methods (``p``
instants, with and without time scaling)."""

from dqcontrol.controllers.thesis.controller import TrackingController
from dqcontrol.controllers.thesis.local import LocalController
from dqcontrol.controllers.thesis.predictive import (
    PredictiveController,
    PredictiveNoScalingController,
)

__all__ = [
    "LocalController",
    "PredictiveController",
    "PredictiveNoScalingController",
    "TrackingController",
]
