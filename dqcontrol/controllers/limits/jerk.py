"""Joint jerk of the commanded velocity, and the bounds that keep it feasible
(docs/theory.md §8.11).

The arm differentiates the applied commands ``u_k``: ``a_k = (u_k - u_{k-1})/T`` and
``j_k = (a_k - a_{k-1})/T``. With ``u_1 = qd_prev`` and ``u_2 = qd_before_prev``:

- applied jerk (hard, with the acceleration bound): ``|qd_0 - 2 u_1 + u_2| ≤ j̄ T²``,
  intersected with ``|qd_0 - u_1| ≤ T ā``;
- velocity with jerk (soft): accelerating towards ``v̄`` the arm needs ``a²/(2 j̄)`` of
  velocity to bring ``a`` back to 0, so ``qd_0 + a_0²/(2 j̄) ≤ v̄``;
- braking with jerk (soft): the stop before a position limit counts the time to turn the
  acceleration round from its largest next value to ``-b`` and the end of the stop, where
  the deceleration is brought back to 0;
- over a horizon of intervals ``Δ_i`` (``horizon_s``): with ``h_0 = T``,
  ``h_i = ½(Δ_{i-1} + Δ_i)`` and ``A_i = (qd_i - qd_{i-1})/h_i`` (``qd_{-1} = u_1``, the
  acceleration rows' definition), ``|A_{i+1} - A_i| ≤ j̄ ½(h_i + h_{i+1})``, each row
  multiplied by ``½(h_i + h_{i+1})`` (velocity units).

Joints without a finite jerk limit get no rows.
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.base import per_joint
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import Bounds, DecisionLayout, Inequality
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.errors import ParameterError
from dqcontrol.model.robot import RobotModel

__all__ = ["JerkLimit", "jerk_limits", "jerk_setting", "terminal_jerk_distance"]

#: The braking deceleration ``b`` is at most this many ``j̄ T``: following the braking
#: envelope to rest, the deceleration fades from ``b`` to 0 over a few periods, and changes
#: by at most ``b/4`` in one of them (docs/theory.md §8.11).
ENVELOPE_JERK_RATIO = 2.0


def jerk_setting(robot: RobotModel, jerk_limit: float | np.ndarray | None) -> np.ndarray | None:
    """The per-joint jerk bound [rad/s³]: ``jerk_limit`` where given, else the robot's
    ``qddd_max``; ``None`` where no joint has a finite one (no jerk rows)."""
    n = robot.nq
    if jerk_limit is None:
        jerk = np.asarray(robot.limits.qddd_max, dtype=float)
        if jerk.shape != (n,) or np.any(np.isnan(jerk)) or np.any(jerk <= 0.0):
            raise ParameterError(
                f"robot.limits.qddd_max must hold {n} values > 0 [rad/s³] (inf: none), "
                f"got {robot.limits.qddd_max!r}"
            )
        return jerk.copy() if np.any(np.isfinite(jerk)) else None
    return per_joint("jerk_limit", jerk_limit, n, "rad/s³")


def jerk_limits(
    jerk: np.ndarray | None,
    layout: DecisionLayout,
    period_s: float,
    qd_max: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    horizon_s: np.ndarray | None = None,
    a_bound: np.ndarray | float | None = None,
) -> tuple[Limit, ...]:
    """``(JerkLimit(...),)``, or ``()`` without a jerk bound (``jerk`` is ``None``)."""
    if jerk is None:
        return ()
    bound = cast("np.ndarray | None", a_bound)  # a scalar broadcasts like an array
    return (JerkLimit(layout, period_s, jerk, qd_max, q_min, q_max, horizon_s, bound),)


def terminal_jerk_distance(a_max: np.ndarray, jerk: np.ndarray) -> np.ndarray:
    """``ā/(2 j̄)`` [s]: what a jerk bound adds to the terminal braking coefficient
    ``v̄/(2 ā)`` (the stop from ``v`` at rest acceleration covers ``v²/(2ā) + v ā/(2j̄)``)."""
    return a_max / (2.0 * jerk)


class JerkLimit(Limit):
    """The jerk bound of the applied command (with its feasibility bounds) and, over a
    horizon, the jerk rows between intervals.

    Args:
        layout: the decision layout.
        period_s: control period ``T`` [s].
        jerk: ``j̄`` [rad/s³] per joint (``inf``: no rows for that joint).
        qd_max: velocity bound ``v̄`` [rad/s] per joint.
        q_min, q_max: position bounds [rad] (already shrunk by any margin).
        horizon_s: ``h_i`` for ``i = 1 … p-1`` [s] (the unreduced acceleration coupling of
            the intervals); ``None``: the applied command only.
        a_bound: the largest ``ā`` [rad/s²] per joint the steps may give (``None``:
            unknown). A horizon row with ``j̄ ½(h_i + h_{i+1}) ≥ 2 ā`` cannot bind (the two
            accelerations it compares are each within ``ā``) and is left out.
    """

    name = "jerk"

    def __init__(
        self,
        layout: DecisionLayout,
        period_s: float,
        jerk: np.ndarray,
        qd_max: np.ndarray,
        q_min: np.ndarray,
        q_max: np.ndarray,
        horizon_s: np.ndarray | None = None,
        a_bound: np.ndarray | None = None,
    ) -> None:
        self.period_s = float(period_s)
        self.jerk = np.asarray(jerk, dtype=float)
        self.qd_max = np.asarray(qd_max, dtype=float)
        self.q_min, self.q_max = np.asarray(q_min, dtype=float), np.asarray(q_max, dtype=float)
        self._active = np.flatnonzero(np.isfinite(self.jerk))
        self._index = frozen(layout.qd_index()[0][self._active])  # the active joints' qd_0
        self._c: np.ndarray | None = None
        if horizon_s is not None and layout.num_blocks > 1:
            n = layout.num_joints
            bound = np.full(n, np.inf) if a_bound is None else np.broadcast_to(a_bound, (n,))
            self._set_horizon(layout, np.asarray(horizon_s, dtype=float), bound)

    def _set_horizon(self, layout: DecisionLayout, coupling_s: np.ndarray, a_bound) -> None:
        """The rows ``m_r (A_{r+1} - A_r)`` over ``qd`` that can bind, and their bounds."""
        h = np.concatenate(([self.period_s], coupling_s))  # h_0 … h_{p-1}
        m = 0.5 * (h[:-1] + h[1:])  # m_0 … m_{p-2}
        idx = layout.qd_index()
        rows, half, first = [], [], []
        for r in range(layout.num_blocks - 1):
            for joint in self._active:
                if self.jerk[joint] * m[r] >= 2.0 * a_bound[joint]:
                    continue  # cannot bind
                row = np.zeros(layout.num_vars)
                row[idx[r + 1, joint]] = m[r] / h[r + 1]
                row[idx[r, joint]] = -m[r] / h[r + 1] - m[r] / h[r]
                if r >= 1:
                    row[idx[r - 1, joint]] = m[r] / h[r]
                else:
                    first.append(joint)
                rows.append(row)
                half.append(self.jerk[joint] * m[r] ** 2)
        if not rows:
            return
        self._c = frozen(np.array(rows))
        self._half = frozen(np.array(half))
        self._first_joints = frozen(np.array(first, dtype=np.int64))  # rows 0 … len - 1
        self._u1_weight = m[0] / h[0]  # the first rows read u_1 as qd_{-1}

    def applied_box(self, ctx: StepContext) -> np.ndarray:
        """``[soft lo; soft up; hard lo; hard up]`` ``(4, n)`` of ``qd_0`` [rad/s] (a new
        array)."""
        u2 = ctx.qd_prev if ctx.qd_before_prev is None else ctx.qd_before_prev
        box = np.empty((4, self.jerk.shape[0]))
        applied_jerk_box(
            ctx.q, ctx.qd_prev, u2, ctx.a_max[0], self.jerk, self.qd_max, self.q_min,
            self.q_max, self.period_s, box,
        )  # fmt: skip
        return box

    def rows(self, ctx: StepContext) -> tuple:
        """The applied command's bounds and, over a horizon, the jerk rows."""
        box = self.applied_box(ctx)
        a = self._active
        if a.size != box.shape[1]:
            box = box[:, a]
        index = self._index
        out: tuple = (
            Bounds("jerk_feasible", index, box[0], box[1]),
            Bounds("jerk_applied", index, box[2], box[3], hard=True),
        )
        if self._c is None:
            return out
        lower, upper = -self._half, self._half.copy()
        first = self._first_joints
        shift = self._u1_weight * ctx.qd_prev[first]  # the first rows' constant, moved over
        lower[: first.size] -= shift
        upper[: first.size] -= shift
        return (*out, Inequality("jerk_horizon", self._c, lower, upper))


@compiled
def _reach(c: float, d: float) -> float:
    """The largest ``x ≥ 0`` with ``x²/(2c) + x ≤ d`` (0 for ``d ≤ 0``)."""
    if d <= 0.0:
        return 0.0
    return -c + math.sqrt(c * c + 2.0 * c * d)


@compiled
def _braking_speed(d: float, a_next: float, b: float, j: float, period_s: float) -> float:
    """The largest speed towards a limit ``d`` [rad] away from which the arm, whose next
    acceleration towards it is at most ``a_next``, stops before it under ``b``, ``j̄``:
    ``w = v + a⁺²/(2j̄)`` bounds the speed while the acceleration turns round (for
    ``L = (a⁺ + b)/j̄``), then ``w²/(2b)`` and the fading of the deceleration, ``b³/(24 j̄²)``;
    with the period's own advance ``T v``: ``w²/(2b) + (L + T) w ≤ d + T a⁺²/(2j̄) - b³/(24j̄²)``."""
    a_up = a_next if a_next > 0.0 else 0.0
    eps = a_up * a_up / (2.0 * j)
    lead = (a_up + b) / j + period_s
    room = d + period_s * eps - b * b * b / (24.0 * j * j)
    w = _reach(b * lead, room / lead)  # w²/(2 b lead) + w ≤ room / lead
    return w - eps


@compiled
def applied_jerk_box(
    q: np.ndarray,
    u1: np.ndarray,
    u2: np.ndarray,
    a_max: np.ndarray,
    jerk: np.ndarray,
    qd_max: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    period_s: float,
    out: np.ndarray,
) -> None:
    """Per joint: ``out[0:2]`` the soft bounds (velocity and braking with jerk),
    ``out[2:4]`` the hard ones (jerk ∩ acceleration; where they do not meet, the end of the
    acceleration interval nearest the jerk one). Joints with ``j̄ = inf``: open soft bounds,
    the acceleration interval."""
    t = period_s
    for k in range(q.shape[0]):
        a, j = a_max[k], jerk[k]
        lo_a, hi_a = u1[k] - t * a, u1[k] + t * a
        if not math.isfinite(j):
            out[0, k], out[1, k], out[2, k], out[3, k] = -np.inf, np.inf, lo_a, hi_a
            continue
        centre, half = 2.0 * u1[k] - u2[k], j * t * t
        lo, hi = max(centre - half, lo_a), min(centre + half, hi_a)
        if lo > hi:
            lo = hi = lo_a if centre + half < lo_a else hi_a
        out[2, k], out[3, k] = lo, hi
        # velocity: x = qd_0 - u_1 with u_1 + x + x²/(2 j̄ T²) ≤ v̄
        c = j * t * t
        up = u1[k] + _reach(c, qd_max[k] - u1[k])
        down = u1[k] - _reach(c, qd_max[k] + u1[k])
        # braking before the position limits, at b, from the largest next acceleration
        b = min(a, ENVELOPE_JERK_RATIO * j * t)
        acc = (u1[k] - u2[k]) / t
        up = min(up, _braking_speed(q_max[k] - q[k], min(acc + j * t, a), b, j, t))
        down = max(down, -_braking_speed(q[k] - q_min[k], min(-acc + j * t, a), b, j, t))
        out[0, k], out[1, k] = down, up
