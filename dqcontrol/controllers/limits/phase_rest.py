"""The task ends at rest on the path: ``s_i ≤ √(2 b_i (T_tot - σ_i))`` (docs/theory.md §8.9).

The phase has its own dynamics ``σ̇ = s``. Braking it at a constant deceleration ``b`` from
``s`` takes ``s²/(2 b)`` of phase, so ``s ≤ √(2 b (T_tot - σ))`` at every phase brings
``s`` to 0 exactly at ``σ = T_tot``. Along the path the joints move at ``q' s`` with
``q' = ∂q/∂σ``, so a phase deceleration ``b`` asks ``|q'_j| b`` of joint ``j``; with
``b = share · min_j a_max,j / |q'_j|`` the braking uses at most ``share`` of every joint's
acceleration bound (the rest is left for the path's curvature, ``q'' s²``, and for the
path level's corrections). ``q'`` is the least-squares solution of ``J(q̄_i) q' = x_d'(σ̄_i)``
at each predicted state of the plan.

Interval ``i`` starts at the phase ``σ_i = σ + Σ_{j<i} Δ_j s_j``, linear in the decision; the
square root is linearised at the plan's phase ``σ̄_i`` (exact for the applied interval,
whose ``σ_0 = σ`` is known):

    s_i + (b_i / f_i) Σ_{j<i} Δ_j s_j ≤ f_i + (b_i / f_i) (σ̄_i - σ),   f_i = √(2 b_i r̄_i),

with ``r̄_i = T_tot - σ̄_i`` (at least :data:`MIN_REMAINING_PERIODS` periods' worth of
braking, where the slope would be unbounded). One more row, ``σ + Σ_j Δ_j s_j ≤ T_tot``,
lets the phase reach the end exactly and never pass it. Rows that cannot bind (the plan's
phase, advancing at ``s_max``, still leaves ``f_i ≥ s_max``) are not posed, so far from the
end the problem is the one without this limit.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Inequality
from dqcontrol.controllers.limits.limit import Limit

__all__ = ["PhaseRestLimit", "phase_speed_per_joint"]

#: Smallest remaining phase the square root is linearised at, in periods of braking
#: ``b T²`` (below it the tangent's slope ``b / f`` would grow without bound).
MIN_REMAINING_PERIODS = 0.5
#: Range of the phase deceleration ``b`` [1/s]: a path point with ``q' = 0`` would give an
#: unbounded ``b``; a singular one a vanishing ``b``.
B_MIN, B_MAX = 1e-2, 1e4
#: The rows are evaluated while the end is within this many braking distances (plus the
#: horizon); the braking distance is re-measured whenever they are.
REACH_FACTOR = 4.0


#: Regularisation of ``JᵀJ`` in :func:`phase_speed_per_joint` (relative to its trace): the
#: least-norm solution where the arm is redundant, to rounding.
REGULARISATION = 1e-12


def phase_speed_per_joint(jacobians: np.ndarray, tangents: np.ndarray) -> np.ndarray:
    """``|∂q/∂σ|`` per joint ``(p, n)`` [rad per s of phase]: the least-norm ``q'`` of
    ``J q' = x_d'`` at each state (``jacobians`` ``(p, 8, n)``, ``tangents`` ``(p, 8)``),
    ``q' = Jᵀ y`` with ``(J Jᵀ + ε I) y = x_d'`` (``ε``: :data:`REGULARISATION` of the
    mean diagonal). The dual quaternion's Jacobian has rank 6 at most, so either Gram matrix
    is singular; in this form the rounding that ``ε`` amplifies lies in ``J``'s left null
    space, which ``Jᵀ`` removes (docs/theory.md §8.9)."""
    jt = jacobians.transpose(0, 2, 1)
    gram = jacobians @ jt
    m = gram.shape[-1]
    scale = REGULARISATION * np.trace(gram, axis1=1, axis2=2) / m + 1e-300
    gram += scale[:, None, None] * np.eye(m)
    dq = jt @ np.linalg.solve(gram, tangents[:, :, None])
    return np.abs(dq[:, :, 0])


class PhaseRestLimit(Limit):
    """The phase velocity brakes to 0 at ``σ = T_tot`` within ``share`` of ``a_max``.

    Args:
        layout: the decision layout (with the time scaling).
        s_max: largest time scaling.
        share: share of each joint's acceleration bound the phase's braking may use.
    """

    name = "phase_rest"

    def __init__(self, layout: DecisionLayout, s_max: float, share: float = 0.5) -> None:
        self.layout = layout
        self.s_max = float(s_max)
        self.share = float(share)
        durations = layout.durations_s
        self._starts_s = np.concatenate(([0.0], np.cumsum(durations)[:-1]))
        self._s_index = layout.s_index()
        self._reach: tuple[object, float, float] = (None, np.inf, np.inf)

    def decelerations(self, ctx: StepContext) -> np.ndarray:
        """``b_i`` [1/s] at every predicted state ``(p,)``."""
        speed = phase_speed_per_joint(ctx.jacobians, ctx.target_derivatives)
        a_max = np.broadcast_to(ctx.a_max, speed.shape)
        with np.errstate(divide="ignore"):
            ratio = np.where(speed > 0.0, a_max / np.maximum(speed, 1e-300), np.inf)
        return np.clip(self.share * np.min(ratio, axis=1), B_MIN, B_MAX)

    def speed_share(self, trajectory: object, sigma: float) -> float:
        """``min(1, √(2 b (T_tot - σ)) / s_max)`` with the last measured ``b``: the share of
        its nominal speed a motion may keep at phase ``σ`` to reach rest with the phase
        (1 before any measurement)."""
        traj, _, reach = self._reach
        left = trajectory.duration - sigma  # type: ignore[attr-defined]
        if traj is not trajectory or left >= reach:
            return 1.0
        return float(np.sqrt(max(left, 0.0) / reach))

    def _far(self, ctx: StepContext, left: float) -> bool:
        """Whether the end is beyond every row's reach (the last measured braking distance,
        :data:`REACH_FACTOR` times, plus the horizon at ``s_max``)."""
        traj, sigma_seen, reach = self._reach
        if traj is not ctx.trajectory or ctx.sigma < sigma_seen:
            return False
        return left > REACH_FACTOR * reach + self.s_max * float(self.layout.durations_s.sum())

    def rows(self, ctx: StepContext) -> Inequality | None:
        """The braking rows that may bind, and the row that ends the phase at ``T_tot``."""
        left = ctx.trajectory.duration - ctx.sigma
        if self._far(ctx, left):
            return None
        b = self.decelerations(ctx)
        self._reach = (ctx.trajectory, ctx.sigma, self.s_max**2 / (2.0 * float(b.min())))
        sigma_lin = np.concatenate(([ctx.sigma], ctx.prediction.sigma_lin[:-1]))
        floor = MIN_REMAINING_PERIODS * b * ctx.period_s**2
        remaining = np.maximum(ctx.trajectory.duration - sigma_lin, floor)
        f = np.sqrt(2.0 * b * remaining)
        # the rows that cannot bind: the phase at s_max from now still leaves f ≥ s_max
        least = np.maximum(left - self.s_max * self._starts_s, 0.0)
        active = np.flatnonzero(2.0 * b * least < self.s_max**2)
        if active.size == 0:
            return None
        return self._inequality(ctx, active, b, f, sigma_lin, max(left, 0.0))

    def _inequality(self, ctx, active, b, f, sigma_lin, left: float) -> Inequality:
        durations = self.layout.durations_s
        slope = b[active] / f[active]
        rows = np.zeros((active.size + 1, self.layout.num_vars))
        cols = self._s_index
        earlier = np.arange(durations.size)[None, :] < active[:, None]
        rows[:-1][:, cols] = slope[:, None] * durations[None, :] * earlier
        rows[np.arange(active.size), cols[active]] = 1.0
        rows[-1, cols] = durations
        upper = np.empty(active.size + 1)
        upper[:-1] = f[active] + slope * (sigma_lin[active] - ctx.sigma)
        upper[-1] = left
        keys = np.append(active, durations.size)
        return Inequality(self.name, rows, np.full(upper.size, -np.inf), upper, keys)
