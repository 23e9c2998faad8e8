"""The applied block's command box (docs/theory.md §5): its velocity/position/braking box at
the measured ``q`` intersected with the hard acceleration bound ``|qd_0 - qd_prev| ≤ T a_max,0``
under the conflict rule, and the acceleration coupling rows of the later blocks.

It is a :class:`~dqcontrol.controllers.limits.joint_box.JointBoxLimit` of the applied block
and an :class:`~dqcontrol.controllers.limits.acceleration.AccelerationLimit` as one limit:
its rows are theirs, under their names; its fast path computes the box and the hard bound
joint by joint in one compiled pass (``joint_box.command_box_into``), where the two limits
would take one pass each.
"""

from __future__ import annotations

from dqcontrol.controllers.core.box_rules import command_box_into
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.limits.acceleration import AccelerationLimit
from dqcontrol.controllers.limits.joint_box import JointBoxLimit
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.errors import ParameterError

__all__ = ["CommandBoxLimit"]


class CommandBoxLimit(Limit):
    """The joint box of the applied block, then the acceleration bound (hard).

    Args:
        box: the applied block's joint box (``predicted=False``); its ``q_min``, ``q_max``,
            ``qd_max`` and ``braking_aware`` are read at every step.
        acceleration: the acceleration bound of the first block and the coupling rows.

    ``hard``: the limit is merged after every soft bound, its own soft box first, then the
    acceleration bound with the conflict rule (what the two limits give merged apart).
    """

    name = "command_box"
    hard = True

    def __init__(self, box: JointBoxLimit, acceleration: AccelerationLimit) -> None:
        if box.predicted:
            raise ParameterError("CommandBoxLimit needs the applied block's joint box")
        self.box = box
        self.acceleration = acceleration

    def rows(self, ctx: StepContext) -> tuple:
        """The joint box's bounds and the acceleration limit's rows."""
        return (self.box.rows(ctx), *self.acceleration.rows(ctx))

    def tighten(self, ctx, lower, upper, conflict) -> bool:
        """Intersect the command box (joint box and acceleration) into ``lower``/``upper``."""
        box = self.box
        command_box_into(
            ctx.q, ctx.qd_prev, box.values, ctx.a_max, ctx.period_s, box.braking_aware, lower,
            upper, conflict,
        )  # fmt: skip
        return True

    def row_bounds(self, ctx, lower, upper) -> bool:
        """The acceleration limit's row bounds (:meth:`AccelerationLimit.row_bounds`)."""
        return self.acceleration.row_bounds(ctx, lower, upper)
