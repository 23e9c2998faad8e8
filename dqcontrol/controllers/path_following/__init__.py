"""The path-following predictive controller (docs/theory.md §8): the controller, its expert
tuning, its compiled kernels and the kinematics it keeps between steps."""

from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.controllers.path_following.tuning import PathFollowingTuning

__all__ = ["PathFollowingController", "PathFollowingTuning"]
