"""Standing still while the task is stalled (docs/theory.md §8.3).

Once the applied ``s`` has stayed near 0 for the stall delay, the task cannot progress
from where the arm is (a path point out of reach, a joint at its limit). The levels then
still answer every change of the measured path error; with measurement noise that is the
noise itself, and the arm keeps moving without the task advancing. While stalled, a plan
that does not progress is therefore not applied: the applied command is the point of the
applied block's bounds closest to zero (the safe fallback's command: braking within
``a_max`` towards rest) and ``s = 0``. A plan that does progress is applied as it is, and
ends the stall.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.qp_controller import Solved

__all__ = ["hold_still"]


def hold_still(solved: Solved, num_joints: int, progress_threshold: float) -> bool:
    """Make the applied block of ``solved``'s solution the command that stands still
    (module docstring), in place, unless its ``s`` reaches ``progress_threshold``.

    Returns whether it did; a step without a solution (the fallback) is left alone.
    """
    if solved.result.failed_level == 0:
        return False
    z = solved.result.solution.x
    problem = solved.problem
    if z is None or problem.lower is None or problem.upper is None:
        return False
    n = num_joints
    if float(z[n]) >= progress_threshold:
        return False
    z[:n] = np.minimum(np.maximum(0.0, problem.lower[:n]), problem.upper[:n])
    z[n] = 0.0
    return True
