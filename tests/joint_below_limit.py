"""A limit written outside the package, in one file: keep joint ``j`` below an angle
(the worked example of docs/theory.md §7.7)."""

from __future__ import annotations

import math

import numpy as np

from dqcontrol.controllers.core.problem import Bounds
from dqcontrol.controllers.limits.limit import Limit


class KeepJointBelow(Limit):
    """``q_j`` stays below ``angle_rad``: the applied command reaches the angle at most at
    the end of the period, and no faster than the joint can still stop there.

    With ``d = angle - q_j``, ``T`` the period and ``a = a_max,j`` of the applied block:
    ``qd_0,j ≤ min(d / T, -a T + sqrt((a T)² + 2 a max(d, 0)))`` (a soft bound: where the
    acceleration bound cannot reach it, the acceleration bound wins and the joint brakes).
    """

    name = "keep_joint_below"

    def __init__(self, joint: int, angle_rad: float) -> None:
        self.joint = int(joint)
        self.angle_rad = float(angle_rad)

    def rows(self, ctx) -> Bounds:
        j, period = self.joint, ctx.period_s
        room = self.angle_rad - float(ctx.q[j])
        at = float(ctx.a_max[0, j]) * period
        brake = -at + math.sqrt(at * at + 2.0 * float(ctx.a_max[0, j]) * max(room, 0.0))
        index = ctx.layout.qd_index()[0, j : j + 1]
        return Bounds(self.name, index, np.array([-np.inf]), np.array([min(room / period, brake)]))
