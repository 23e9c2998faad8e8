"""Limits (docs/theory.md §7.3, §5): the contract, :class:`Limit` (bounds on variables or
inequality rows ``lower ≤ C z ≤ upper``, or nothing when inactive), and the limits the
controllers compose. A new limit is one file here (or anywhere: docs/contributing.md)."""

from dqcontrol.controllers.limits.acceleration import AccelerationLimit
from dqcontrol.controllers.limits.applied_box import AppliedCommandBox
from dqcontrol.controllers.limits.collision import CollisionLimit
from dqcontrol.controllers.limits.command_box import CommandBoxLimit
from dqcontrol.controllers.limits.joint_box import JointBoxLimit
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.limits.phase_end import PhaseEndLimit
from dqcontrol.controllers.limits.predicted_position import PredictedPositionLimit
from dqcontrol.controllers.limits.scaling_range import ScalingRange
from dqcontrol.controllers.limits.torque import TorqueLimit
from dqcontrol.controllers.limits.trust_region import TrustRegionLimit
from dqcontrol.controllers.limits.velocity import VelocityLimit

__all__ = [
    "AccelerationLimit",
    "AppliedCommandBox",
    "CollisionLimit",
    "CommandBoxLimit",
    "JointBoxLimit",
    "Limit",
    "PhaseEndLimit",
    "PredictedPositionLimit",
    "ScalingRange",
    "TorqueLimit",
    "TrustRegionLimit",
    "VelocityLimit",
]
