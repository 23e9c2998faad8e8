"""The applied command's own box: velocity, position through one period, and braking
(docs/theory.md §5), as soft bounds on ``qd_0``.

Merged with the hard acceleration bound of the first block (the conflict rule), this is
the thesis's command box: where a joint moves too fast towards its limit to stop in time,
the acceleration bound is kept and the joint brakes as hard as it allows.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.box_rules import applied_box_into, braking_rows
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import Bounds, DecisionLayout
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.linalg.gram import frozen

__all__ = ["AppliedCommandBox"]


class AppliedCommandBox(Limit):
    """Soft bounds on ``qd_0`` from ``q``: ``|qd| ≤ qd_max``, ``q + T qd`` within the
    limits, and slow enough to stop before them at ``a_max``."""

    name = "applied_box"

    def __init__(
        self,
        layout: DecisionLayout,
        q_min: np.ndarray,
        q_max: np.ndarray,
        qd_max: np.ndarray,
        period_s: float,
    ) -> None:
        self._index = layout.qd_index()[0]
        self.q_min, self.q_max, self.qd_max = q_min, q_max, qd_max
        self.period_s = float(period_s)
        self._brake_key: object = None
        self._brake = np.zeros((3, layout.num_joints))
        self._own = np.arange(layout.num_joints)  # entries of lo/up the kernel merges into
        n = layout.num_joints
        self._open = frozen(np.array([np.full(n, -np.inf), np.full(n, np.inf)]))

    def _braking(self, a_max: np.ndarray) -> np.ndarray:
        """``[a T; 2 a; (a T)²]`` of the first block (kept while ``a_max`` is the same)."""
        if a_max is not self._brake_key:
            self._brake = braking_rows(a_max[0], self.period_s)
            self._brake_key = a_max
        return self._brake

    def rows(self, ctx: StepContext) -> Bounds:
        """The bounds of the applied block."""
        box = self._open.copy()  # [-inf; inf], narrowed by the kernel
        lo, up = box[0], box[1]
        brake = self._braking(ctx.a_max)
        values = (self.q_min, self.q_max, self.qd_max)
        applied_box_into(ctx.q, *values, self.period_s, True, brake, self._own, lo, up)
        return Bounds(self.name, self._index, lo, up)
