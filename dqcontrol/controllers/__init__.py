"""The controllers behind one interface (:class:`Controller`, docs/theory.md §4), and the
composable QP core they are built on (docs/theory.md §7): the contracts of a term, a limit,
a backend (with its registry of names), a priority level and the problem built at each
step, and :class:`QPController`, whose one pipeline steps any composition of them."""

from dqcontrol._blas import single_blas_thread
from dqcontrol.controllers.backends import (
    Backend,
    ForwardingBackend,
    backend_names,
    register_backend,
)
from dqcontrol.controllers.base import Controller, StepDiagnostics, StepResult
from dqcontrol.controllers.core.bounds import Box, command_box, safe_command, velocity_position_box
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import (
    BlockQP,
    Bounds,
    DecisionLayout,
    Inequality,
    Level,
    Problem,
    Residual,
    Solution,
)
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.controllers.path_following.tuning import PathFollowingTuning
from dqcontrol.controllers.prediction import integration_matrix, prediction_instants
from dqcontrol.controllers.proportional import ProportionalController
from dqcontrol.controllers.qp_controller import QPController
from dqcontrol.controllers.terms.term import Term
from dqcontrol.controllers.thesis.controller import QPProblem, TrackingController
from dqcontrol.controllers.thesis.local import LocalController
from dqcontrol.controllers.thesis.predictive import (
    PredictiveController,
    PredictiveNoScalingController,
)

__all__ = [
    "Backend",
    "ForwardingBackend",
    "backend_names",
    "register_backend",
    "PathFollowingController",
    "PathFollowingTuning",
    "BlockQP",
    "Bounds",
    "Box",
    "Controller",
    "DecisionLayout",
    "Inequality",
    "Level",
    "Limit",
    "LocalController",
    "PredictiveController",
    "PredictiveNoScalingController",
    "Problem",
    "ProportionalController",
    "QPController",
    "QPProblem",
    "Residual",
    "Solution",
    "StepContext",
    "StepDiagnostics",
    "StepResult",
    "Term",
    "TrackingController",
    "command_box",
    "integration_matrix",
    "prediction_instants",
    "safe_command",
    "single_blas_thread",
    "velocity_position_box",
]
