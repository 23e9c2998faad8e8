"""Cost terms (docs/theory.md §7.3): the contract, :class:`Term` (residual rows ``A z - b``
with a weight), and the terms the controllers compose. A new term is one file here (or
anywhere: docs/contributing.md)."""

from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.controllers.terms.path_error import PathErrorTerm
from dqcontrol.controllers.terms.posture import PostureTerm
from dqcontrol.controllers.terms.progress import ProgressTerm
from dqcontrol.controllers.terms.scaling import ScalingTerm
from dqcontrol.controllers.terms.scaling_smoothness import ScalingSmoothnessTerm
from dqcontrol.controllers.terms.singularity_damping import SingularityDampingTerm
from dqcontrol.controllers.terms.stall_damping import StallDampingTerm
from dqcontrol.controllers.terms.term import Term
from dqcontrol.controllers.terms.tracking import TrackingTerm

__all__ = [
    "DampingTerm",
    "PathErrorTerm",
    "PostureTerm",
    "ProgressTerm",
    "ScalingSmoothnessTerm",
    "ScalingTerm",
    "SingularityDampingTerm",
    "StallDampingTerm",
    "Term",
    "TrackingTerm",
]
