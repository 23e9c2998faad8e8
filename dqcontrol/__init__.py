"""dqcontrol: kinematic control of redundant manipulators with dual quaternions.

The pipeline, one sub-package per stage: ``model`` (URDF → Pinocchio) → ``dq`` (the
dual-quaternion layer) → ``trajectories`` → ``controllers`` (QP building, then solving) →
``sim`` (kinematic and MuJoCo loops) → ``viz`` and ``metrics``.
"""

from dqcontrol.errors import (
    ConfigurationError,
    DQControlError,
    FrameError,
    ParameterError,
    SolverError,
    URDFError,
)
from dqcontrol.model import JointLimits, RobotModel, load_lbr4p, load_panda

__version__ = "0.1.0"

__all__ = [
    "ConfigurationError",
    "DQControlError",
    "FrameError",
    "JointLimits",
    "ParameterError",
    "RobotModel",
    "SolverError",
    "URDFError",
    "load_lbr4p",
    "load_panda",
]
