"""A jerk-limited velocity tracker: the command of each period moves towards a target
velocity without passing the velocity, acceleration and jerk limits (docs/theory.md §12.2).

The robot differentiates the commands ``u_k`` sent every ``T``: ``a_k = (u_k - u_{k-1})/T``
and ``j_k = (a_k - a_{k-1})/T``. Each period the tracker picks ``a_k`` within

* ``|a_k - a_{k-1}| ≤ j̄ T`` (jerk) and ``|a_k| ≤ ā`` (acceleration),
* ``u_{k-1} + D(a_k) ≤ v̄`` and ``u_{k-1} - D(-a_k) ≥ -v̄``, where ``D(a)`` is the velocity
  still gained while ``a`` is brought to zero by ``j̄ T`` per period (counting this period):
  the limit can always be kept, since the set is never empty once it was not
  (``a_{k-1} - j̄ T`` satisfies it whenever ``a_{k-1}`` did),

as close as possible to the acceleration that reaches the target ``r`` without overshoot
(the same ``D`` with ``r`` in place of ``v̄``). Infinite limits give ``u_k = r`` exactly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["JerkLimitedTracker", "reachable_acceleration"]


def reachable_acceleration(gap: np.ndarray, jerk_step: np.ndarray, period_s: float) -> np.ndarray:
    """The largest ``a ≥ 0`` whose velocity gain ``D(a)`` until it is brought to zero by
    ``jerk_step = j̄ T`` per period is at most ``gap ≥ 0`` [rad/s] (``gap / T`` where the
    jerk is unbounded).

    With ``a = m j̄ T`` the gain is ``j̄ T² m (m + 1)/2``; between two such values it grows
    by ``T (m + 1)`` per unit of ``a``.
    """
    gap = np.maximum(gap, 0.0)
    finite = np.isfinite(jerk_step)
    d = np.where(finite, jerk_step, 1.0) * period_s  # j̄ T² (1 where unbounded)
    m = np.floor(0.5 * (np.sqrt(1.0 + 8.0 * gap / d) - 1.0))
    m = np.maximum(m, 0.0)
    used = 0.5 * d * m * (m + 1.0)
    # rounding can put the integer one too high: step back where it overshoots the gap
    over = used > gap
    m = np.where(over, m - 1.0, m)
    used = np.where(over, 0.5 * d * m * (m + 1.0), used)
    a = m * np.where(finite, jerk_step, 0.0) + (gap - used) / (period_s * (m + 1.0))
    return np.where(finite, a, gap / period_s)


class JerkLimitedTracker:
    """The command ``u`` and its acceleration ``a`` (the robot's finite differences),
    moved towards a target each period within ``qd_max``, ``qdd_max``, ``qddd_max``.

    Args:
        qd_max, qdd_max, qddd_max: per joint [rad/s], [rad/s²], [rad/s³] (``inf``: none).
        period_s: ``T`` [s].
    """

    def __init__(
        self, qd_max: np.ndarray, qdd_max: np.ndarray, qddd_max: np.ndarray, period_s: float
    ) -> None:
        self.qd_max = np.asarray(qd_max, dtype=float)
        self.qdd_max = np.asarray(qdd_max, dtype=float)
        self.jerk_step = np.asarray(qddd_max, dtype=float) * period_s  # j̄ T [rad/s²]
        self.period_s = float(period_s)
        self.u = np.zeros(self.qd_max.size)
        self.a = np.zeros(self.qd_max.size)

    def restart(self, u: np.ndarray, a: np.ndarray) -> None:
        """Set the last command [rad/s] and its acceleration [rad/s²]."""
        self.u, self.a = np.array(u, dtype=float), np.array(a, dtype=float)

    def copy(self) -> JerkLimitedTracker:
        """An independent copy (the limits shared, the state copied)."""
        twin = object.__new__(JerkLimitedTracker)
        twin.__dict__.update(self.__dict__)
        twin.u, twin.a = self.u.copy(), self.a.copy()
        return twin

    def step(self, target: np.ndarray) -> np.ndarray:
        """The next command [rad/s], as close to ``target`` as the limits allow."""
        u, a, T, js = self.u, self.a, self.period_s, self.jerk_step
        r = np.clip(target, -self.qd_max, self.qd_max)
        v_max, a_max = self.qd_max, self.qdd_max
        hi = np.minimum(np.minimum(a + js, a_max), reachable_acceleration(v_max - u, js, T))
        lo = np.maximum(np.maximum(a - js, -a_max), -reachable_acceleration(v_max + u, js, T))
        gap = r - u
        wanted = np.where(
            gap >= 0.0, reachable_acceleration(gap, js, T), -reachable_acceleration(-gap, js, T)
        )
        a_new = np.minimum(np.maximum(wanted, lo), hi)
        u_new = u + a_new * T
        # where the target is reached this period, send it exactly
        reached = (a_new == wanted) & (np.abs(u_new - r) <= 1e-12 * (1.0 + np.abs(r)))
        u_new = np.where(reached, r, u_new)
        self.a = (u_new - u) / T
        self.u = u_new
        return u_new
