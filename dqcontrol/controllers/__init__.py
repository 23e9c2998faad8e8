"""The four controllers of FORMULATION §5 behind one interface (:class:`Controller`)."""

from dqcontrol.controllers.base import Controller, StepDiagnostics, StepResult
from dqcontrol.controllers.bounds import Box, command_box, safe_command, velocity_position_box
from dqcontrol.controllers.local import LocalController
from dqcontrol.controllers.prediction import integration_matrix, prediction_instants
from dqcontrol.controllers.predictive import PredictiveController, PredictiveNoScalingController
from dqcontrol.controllers.proportional import ProportionalController
from dqcontrol.controllers.tracking import QPProblem, TrackingController

__all__ = [
    "Box",
    "Controller",
    "LocalController",
    "PredictiveController",
    "PredictiveNoScalingController",
    "ProportionalController",
    "QPProblem",
    "StepDiagnostics",
    "StepResult",
    "TrackingController",
    "command_box",
    "integration_matrix",
    "prediction_instants",
    "safe_command",
    "velocity_position_box",
]
