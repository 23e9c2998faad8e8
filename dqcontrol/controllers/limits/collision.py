"""Collision avoidance as a limit: self-collision and obstacles (docs/theory.md §10).

For every pair of a :class:`~dqcontrol.model.collision.CollisionModel` closer than the
influence distance ``d_i``, with distance ``d`` and gradient ``∇d`` (witness points, normal and
point Jacobians, §10.1):

- **states are data** (the thesis's prediction, ``weights = 0``: the local and the thesis's
  predictive controllers): a velocity damper on the applied command (§10.2),

      ∇dᵀ q̇_0 ≥ -k max(d - d_s, 0),     k = min(ξ / (d_i - d_s), 1/T),

  evaluated at the measured ``q``; the cap ``1/T`` keeps one period from using more than the
  margin left, and a pair already inside the safety distance may not come closer (rather
  than being asked to leave at a rate the acceleration bound may forbid);
- **states are affine in the decision** (the consistent prediction of the path-following
  controller, ``q_i(z) = q_base,i + Σ_j W_ij q̇_j``): the distance linearised at each predicted
  state's linearisation point ``q̄_i`` (§10.3),

      d(q̄_i) + ∇d(q̄_i)ᵀ (q_i(z) - q̄_i) ≥ min(d_s, d(q) - u_i),

  where ``d(q)`` is the pair's distance at the measured state and ``u_i`` the approach the
  pair cannot avoid by state ``i``'s time when it is closing now, braking at a share of the
  acceleration bound (a pair already inside the safety distance, or closing on it faster
  than the bound can stop, may not come closer than braking brings it, rather than being
  asked for what no command reaches).

The limit is inactive (no rows) while every pair is further than ``d_i``. Its rows change
with the pairs and the configuration, so a controller's backend sets up again at every step
with rows. Each row is named by its pair (and predicted state): where pairs come and go, a
backend carries its last active set to the rows that stay (docs/theory.md §7.5).
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import Inequality
from dqcontrol.controllers.limits.collision_rows import damper_rows, predicted_rows
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.errors import ParameterError
from dqcontrol.model.collision import CollisionModel

__all__ = ["CollisionLimit"]

#: Accepted ranges of the parameters: influence and safety distances [m], gain [m/s].
INFLUENCE_RANGE_M = (1e-3, 1.0)
SAFETY_RANGE_M = (0.0, 0.5)
GAIN_RANGE_M_PER_S = (1e-3, 10.0)
#: Share of the acceleration bound the predicted rows count on to brake a pair's approach
#: (docs/theory.md §10.3): all of it, so that a floor drops below the safety distance only
#: where no command within the bound could have kept the pair out.
BRAKING_SHARE = 1.0


def _in_range(name: str, value, bounds: tuple[float, float], unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number [{unit}], got {value!r}") from None
    lo, hi = bounds
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ParameterError(f"{name} must be in [{lo:g}, {hi:g}] [{unit}], got {value!r}")
    return v


class CollisionLimit(Limit):
    """Keep every pair of ``collision`` at least ``safety_distance_m`` apart.

    Args:
        collision: the robot's collision model with its obstacles and pairs.
        influence_distance_m: ``d_i`` [m]: pairs closer than this get rows (0.10).
        safety_distance_m: ``d_s`` [m], ``< d_i``: the distance kept (0.02).
        gain_m_per_s: ``ξ`` [m/s]: the approach speed the damper allows at ``d_i``,
            falling linearly to 0 at ``d_s`` (0.5).

    Attributes:
        last_min_distance_m: the smallest distance at the measured state at the last step
            (``inf`` when no pair was within ``d_i``).
        last_rows: rows given at the last step.
        pairs_in_influence: pairs within ``d_i`` (summed over the states) at the last step.
    """

    name = "collision"

    def __init__(
        self,
        collision: CollisionModel,
        *,
        influence_distance_m: float = 0.10,
        safety_distance_m: float = 0.02,
        gain_m_per_s: float = 0.5,
    ) -> None:
        if not isinstance(collision, CollisionModel):
            raise ParameterError(
                f"collision must be a CollisionModel, got {type(collision).__name__}"
            )
        self.collision = collision
        self.influence_m = _in_range(
            "influence_distance_m", influence_distance_m, INFLUENCE_RANGE_M, "m"
        )
        self.safety_m = _in_range("safety_distance_m", safety_distance_m, SAFETY_RANGE_M, "m")
        if not self.safety_m < self.influence_m:
            raise ParameterError(
                f"safety_distance_m ({safety_distance_m!r}) must be < influence_distance_m "
                f"({influence_distance_m!r}) [m]"
            )
        self.gain_m_per_s = _in_range("gain_m_per_s", gain_m_per_s, GAIN_RANGE_M_PER_S, "m/s")
        self.last_min_distance_m = math.inf
        self.last_rows = 0
        self.pairs_in_influence = 0
        self._key: tuple | None = None
        self._rows: Inequality | None = None

    def reset(self) -> None:
        """Forget the cached rows."""
        self._key = None
        self._rows = None

    def rows(self, ctx: StepContext) -> Inequality | None:
        """One row per pair closer than the influence distance, or ``None`` when none is."""
        pred = ctx.prediction
        if ctx.robot.nq != self.collision.robot.nq:
            raise ParameterError(
                f"the collision model has {self.collision.robot.nq} joints, the controller's "
                f"robot {ctx.robot.nq}"
            )
        consistent = np.count_nonzero(pred.weights) > 0
        key: tuple = (ctx.q.tobytes(), ctx.qd_prev.tobytes(), float(ctx.period_s))
        if consistent:
            key += (pred.q_lin.tobytes(), pred.q_base.tobytes(), pred.weights.tobytes())
        if key == self._key:  # the same step asked again (set-up, then bounds)
            return self._rows
        out = self._predicted(ctx) if consistent else self._damper(ctx)
        self._key, self._rows = key, out
        self.last_rows = 0 if out is None else int(out.lower.size)
        return out

    # ------------------------------------------------------------------ the two forms
    def _damper(self, ctx: StepContext) -> Inequality | None:
        """``∇dᵀ q̇_0 ≥ -k max(d - d_s, 0)`` for the pairs within ``d_i`` at the measured
        ``q`` (a pair whose penetration query failed gives no row)."""
        batch = self.collision.query_batch(ctx.q[None, :], self.influence_m)
        layout = ctx.layout
        rate = min(self.gain_m_per_s / (self.influence_m - self.safety_m), 1.0 / ctx.period_s)
        c, lower, keys, closest = damper_rows(
            batch.pair,
            batch.distance_m,
            batch.gradient,
            self.safety_m,
            rate,
            layout.qd_index()[0],
            layout.num_vars,
        )
        return self._inequality(c, lower, keys, closest)

    def _predicted(self, ctx: StepContext) -> Inequality | None:
        """``∇d(q̄_i)ᵀ Σ_j W_ij q̇_j ≥ min(d_s, d(q)) - d(q̄_i) + ∇d(q̄_i)ᵀ (q̄_i - q_base,i)``
        at every predicted state (one batched query: the measured state, then the
        linearisation points)."""
        pred, layout = ctx.prediction, ctx.layout
        qs = np.concatenate((ctx.q[None, :], pred.q_lin))
        batch = self.collision.query_batch(qs, self.influence_m)
        times_s = layout.instants_s + layout.durations_s  # each predicted state's time
        c, lower, keys, closest = predicted_rows(
            batch.state,
            batch.pair,
            batch.distance_m,
            batch.gradient,
            (pred.weights, pred.q_lin, pred.q_base, times_s),
            (ctx.qd_prev, np.ascontiguousarray(ctx.a_max[0]), BRAKING_SHARE),
            self.safety_m,
            self.collision.num_pairs,
            layout.block_size,
            layout.num_vars,
        )
        return self._inequality(c, lower, keys, closest)

    def _inequality(
        self, c: np.ndarray, lower: np.ndarray, keys: np.ndarray, closest_m: float
    ) -> Inequality | None:
        """The rows ``c z ≥ lower`` named by ``keys`` (``None`` without any), remembering the
        closest distance [m] and the number of pairs within the influence distance."""
        self.last_min_distance_m = closest_m
        self.pairs_in_influence = int(lower.size)
        if not lower.size:
            return None
        return Inequality(self.name, c, lower, np.full(lower.size, np.inf), keys)
