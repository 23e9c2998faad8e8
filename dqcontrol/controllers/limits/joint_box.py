"""Joint velocity and position, with braking: the box of each block's command
(docs/theory.md §5, thesis eq. 3.8–3.13, 3.19–3.20).

For a command ``qd`` held for one period ``T`` from the joint position ``q``:

- velocity ``-qd_max ≤ qd ≤ qd_max``;
- position through one period ``(q_min - q)/T ≤ qd ≤ (q_max - q)/T``;
- braking (``braking_aware``): slow enough to stop before the limit decelerating at
  ``a_max``: ``T v + v²/(2 a_max) ≤ q_max - q``.

The applied block (``predicted=False``) is bounded at the measured ``q``; the predicted
blocks ``i ≥ 1`` (``predicted=True``) at ``q̂_i`` clipped to the limits (a box that always
contains 0). Beyond a limit the box only allows moving back. Merged with the hard
acceleration bound (:class:`~dqcontrol.controllers.limits.acceleration.AccelerationLimit`)
this is the command box of docs/theory.md §5, conflict rule included.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.box_rules import applied_box_into, predicted_boxes_into
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import Bounds, DecisionLayout
from dqcontrol.controllers.limits.limit import Limit

__all__ = ["JointBoxLimit"]


class JointBoxLimit(Limit):
    """The velocity/position/braking box of the applied block or of the predicted ones.

    Args:
        layout: the decision layout.
        q_min, q_max: position bounds [rad] (already shrunk by any margin).
        qd_max: velocity bound [rad/s].
        braking_aware: add the braking bound (``a_max`` from the step context).
        predicted: bound the predicted blocks ``i ≥ 1`` (relaxable: dropped when the
            problem is infeasible) instead of the applied one.

    Attributes:
        values: ``[q_min; q_max; qd_max]`` ``(3, n)`` [rad, rad, rad/s]; ``q_min``,
            ``q_max`` and ``qd_max`` are its rows (assigned values are copied in, in-place
            edits count). Limits given the same array (``other.values = limit.values``)
            share their bounds.

    ``values`` and ``braking_aware`` are read at every step. The fast path writes the box
    straight into the QP's bounds in one compiled call (``joint_box.applied_box_into`` /
    ``predicted_boxes_into``), which :meth:`rows` calls too.
    """

    def __init__(
        self,
        layout: DecisionLayout,
        q_min: np.ndarray,
        q_max: np.ndarray,
        qd_max: np.ndarray,
        braking_aware: bool = True,
        *,
        predicted: bool = False,
    ) -> None:
        self.values = np.array([q_min, q_max, qd_max], dtype=float)
        self.braking_aware = bool(braking_aware)
        self.predicted = bool(predicted)
        self.relaxable = self.predicted
        self.name = "joint_box_predicted" if self.predicted else "joint_box"
        idx = layout.qd_index()
        p, n = idx.shape
        self._index = idx if self.predicted else idx[0]
        # the same kernel into the rows' own arrays: local positions
        local = np.zeros((p, n), dtype=np.int64)
        local[1:] = np.arange((p - 1) * n).reshape(p - 1, n)
        self._local = local if self.predicted else np.arange(n)
        self._global = idx[1:].ravel() if self.predicted else idx[0]
        self._brake_key: tuple = (None, None)
        self._brake = np.zeros((3,) + ((p, n) if self.predicted else (n,)))
        self._kernel = predicted_boxes_into if self.predicted else applied_box_into

    @property
    def q_min(self) -> np.ndarray:
        """Position bounds [rad] (already shrunk by any margin)."""
        return self.values[0]

    @q_min.setter
    def q_min(self, value: np.ndarray) -> None:
        self.values[0] = value

    @property
    def q_max(self) -> np.ndarray:
        """Position bounds [rad] (already shrunk by any margin)."""
        return self.values[1]

    @q_max.setter
    def q_max(self, value: np.ndarray) -> None:
        self.values[1] = value

    @property
    def qd_max(self) -> np.ndarray:
        """Velocity bound [rad/s]."""
        return self.values[2]

    @qd_max.setter
    def qd_max(self, value: np.ndarray) -> None:
        self.values[2] = value

    def braking_constants(self, ctx: StepContext) -> np.ndarray:
        """``[a T, 2 a, (a T)²]`` at each block (``(3, p, n)``, or ``(3, n)`` for the
        applied block), cached while ``ctx.a_max`` and ``T`` stay the same."""
        a_max, period = ctx.a_max, ctx.period_s
        key = self._brake_key
        if a_max is not key[0] or period != key[1]:
            a = a_max if self.predicted else a_max[0]
            at = a * period
            self._brake = np.array([at, 2.0 * a, at * at])
            self._brake_key = (a_max, period)
        return self._brake

    def tighten(self, ctx, lower, upper, conflict) -> bool:
        """Intersect this step's joint boxes into ``lower``/``upper`` (compiled kernel)."""
        key = self._brake_key
        brake = self._brake
        if ctx.a_max is not key[0] or ctx.period_s != key[1]:
            brake = self.braking_constants(ctx)
        q_min, q_max, qd_max = self.values
        self._kernel(
            ctx.prediction.q_lin if self.predicted else ctx.q, q_min, q_max, qd_max,
            ctx.period_s, self.braking_aware, brake, self._index, lower, upper,
        )  # fmt: skip
        return True

    def rows(self, ctx: StepContext) -> Bounds | None:
        """The joint boxes as :class:`Bounds`, or ``None`` without joints to bound."""
        size = self._global.size
        if size == 0:
            return None
        lo = np.full(size, -np.inf)
        up = np.full(size, np.inf)
        q_min, q_max, qd_max = self.values
        self._kernel(
            ctx.prediction.q_lin if self.predicted else ctx.q, q_min, q_max, qd_max,
            ctx.period_s, self.braking_aware, self.braking_constants(ctx), self._local, lo, up,
        )  # fmt: skip
        return Bounds(self.name, self._global, lo, up)
