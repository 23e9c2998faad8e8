"""Joint torques through the inverse dynamics at the predicted states
(docs/theory.md §8.4).

For block ``i`` the command changes from ``qd_{i-1}`` to ``qd_i`` over ``h_i`` (``T`` for the
applied command, from the last applied one); at the block's linearisation state
``(q̄_i, qd̄_i)`` the torque is

    τ_i = M(q̄_i) (qd_i - qd_{i-1}) / h_i + C(q̄_i, qd̄_i) qd̄_i + g(q̄_i),

linear in the decision, and ``|τ_i| ≤ f τ_max`` (``f``: the share of the URDF's effort limits
the plan may use; the rest is left to the joint servos' feedback).

Behind a velocity servo of time constant ``τ_v`` the applied command is not reached over
``T`` but approached from the measured velocity at the rate ``(qd_0 - qd_meas)/τ_v``: the
first block then uses ``h_0 = τ_v`` and the measured velocity (``ctx.qd_now``),
which bounds the servo's own torque peak after the command changes.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Inequality
from dqcontrol.controllers.limits.limit import Limit

__all__ = ["TorqueLimit"]


class TorqueLimit(Limit):
    """Rows ``-f τ_max ≤ M (qd_i - qd_{i-1}) / h_i + b ≤ f τ_max`` for every block.

    Args:
        layout: the decision layout.
        period_s: control period ``T`` [s] (``h_0``).
        coupling_s: ``h_i`` for ``i = 1 … p-1`` [s].
        effort_max: ``τ_max`` [N·m] per joint.
        fraction: ``f`` in ``(0, 1]``.
        first_step_s: ``h_0`` [s] (default ``T``; ``τ_v`` behind a velocity servo).
    """

    name = "torque"

    def __init__(
        self,
        layout: DecisionLayout,
        period_s: float,
        coupling_s: np.ndarray,
        effort_max: np.ndarray,
        fraction: float,
        first_step_s: float | None = None,
    ) -> None:
        self.layout = layout
        first = float(period_s if first_step_s is None else first_step_s)
        self.steps_s = np.concatenate(([first], np.asarray(coupling_s, dtype=float)))
        self.limit = float(fraction) * np.asarray(effort_max, dtype=float)

    def rows(self, ctx: StepContext) -> Inequality:
        """The torque rows of every interval, linearised at its predicted start."""
        layout = self.layout
        p, n = layout.num_blocks, layout.num_joints
        idx = layout.qd_index()
        pred = ctx.prediction
        starts = np.vstack([ctx.q[None, :], pred.q_lin[:-1]])
        c = np.zeros((p * n, layout.num_vars))
        lo = np.empty(p * n)
        up = np.empty(p * n)
        fast = ctx.robot.fast
        plan = pred.warm_qd
        for i in range(p):
            m, _g = fast.mass_gravity(starts[i])
            if i == 0:
                velocity = ctx.qd_now
            else:
                assert plan is not None, "the torque limit's prediction carries the plan"
                velocity = plan[i]
            bias = fast.bias_forces(starts[i], velocity)
            rows = slice(i * n, (i + 1) * n)
            scaled = m / self.steps_s[i]
            c[rows, idx[i]] = scaled
            shift = bias.copy()
            if i == 0:
                shift -= scaled @ ctx.qd_now
            else:
                c[rows, idx[i - 1]] = -scaled
            lo[rows] = -self.limit - shift
            up[rows] = self.limit - shift
        return Inequality(self.name, c, lo, up)
