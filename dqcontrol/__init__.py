"""dqcontrol: kinematic control of redundant manipulators with dual quaternions.

The pipeline, one sub-package per stage: ``model`` (URDF → Pinocchio) → ``dq`` (the
dual-quaternion layer) → ``trajectories`` → ``controllers`` (QP building, then solving) →
``sim`` (kinematic and MuJoCo loops) → ``viz`` and ``metrics``.
"""

from dqcontrol.errors import (
    ConfigurationError,
    DQControlError,
    FrameError,
    MissingExtraError,
    ParameterError,
    SolverError,
    URDFError,
)
from dqcontrol.model import JointLimits, RobotModel, load_lbr4p, load_panda

try:  # the version is defined once, in pyproject.toml; read it from the installed metadata
    from importlib.metadata import version as _metadata_version

    __version__ = _metadata_version("dqcontrol")
except ImportError:  # its subclass PackageNotFoundError: a source tree that was never installed
    __version__ = "0+unknown"

__all__ = [
    "ConfigurationError",
    "DQControlError",
    "FrameError",
    "JointLimits",
    "MissingExtraError",
    "ParameterError",
    "RobotModel",
    "SolverError",
    "URDFError",
    "load_lbr4p",
    "load_panda",
]
