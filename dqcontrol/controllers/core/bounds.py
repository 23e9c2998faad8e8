"""Hard joint bounds on a velocity command (docs/theory.md §5, thesis eq. 3.8–3.13,
3.19–3.20).

For a command ``qd`` applied during one period ``T`` from the joint position ``q``:

- velocity: ``-qd_max ≤ qd ≤ qd_max``;
- position through one period: ``(q_min - q)/T ≤ qd ≤ (q_max - q)/T``;
- acceleration: ``qd_prev - T a_max ≤ qd ≤ qd_prev + T a_max``.

Two additions of ours, both documented in the theory page:

- *braking-aware position bound* (on by default): ``qd`` is also limited to the speed from
  which the joint can still stop before its limit decelerating at ``a_max``:
  ``T v + v²/(2 a_max) ≤ q_max - q`` ⇒ ``v ≤ -a_max T + sqrt((a_max T)² + 2 a_max (q_max - q))``.
  It is never looser than the one-period bound, and it is what keeps the acceleration and
  position bounds from conflicting later.
- *conflict rule*: where the acceleration interval does not meet the others (the joint is
  already moving too fast towards a limit), the acceleration bound is kept and the command
  brakes as hard as it allows: the box collapses to the point of the acceleration interval
  closest to the position/velocity interval.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Box",
    "braking_speed",
    "command_box",
    "intersect_acceleration",
    "safe_command",
    "velocity_position_box",
]


@dataclass(frozen=True)
class Box:
    """Per-joint interval ``lower ≤ qd ≤ upper`` [rad/s]; ``conflict`` marks collapsed joints."""

    lower: np.ndarray
    upper: np.ndarray
    conflict: np.ndarray

    def contains(self, qd: np.ndarray, tol: float = 0.0) -> bool:
        """Whether every joint of ``qd`` lies in the box (within ``tol`` [rad/s])."""
        return bool(np.all(qd >= self.lower - tol) and np.all(qd <= self.upper + tol))

    def project(self, qd: np.ndarray) -> np.ndarray:
        """Closest point of the box to ``qd`` (per joint clip)."""
        return np.minimum(np.maximum(qd, self.lower), self.upper)


def braking_speed(distance: np.ndarray, a_max: np.ndarray, period_s: float) -> np.ndarray:
    """Largest speed [rad/s] towards a limit ``distance`` [rad] away that can still stop.

    Solves ``T v + v²/(2 a) = distance`` for ``v ≥ 0`` (one period at ``v`` then braking at
    ``a``); a non-positive distance gives 0.
    """
    d = np.maximum(distance, 0.0)
    at = a_max * period_s
    return -at + np.sqrt(at * at + 2.0 * a_max * d)


def velocity_position_box(
    q: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    qd_max: np.ndarray,
    period_s: float,
    a_max: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity ∩ position bounds at ``q`` (and braking-aware if ``a_max`` is given).

    Works on a single configuration ``(n,)`` or a batch ``(p, n)``. ``q`` outside the limits
    gives a box that only allows moving back (or standing still if the velocity bound
    forbids more).
    """
    q = np.asarray(q, dtype=float)
    if a_max is None:
        return _vp_box(q, q_min, q_max, qd_max, period_s, None)
    at = a_max * period_s
    return _vp_box(q, q_min, q_max, qd_max, period_s, (at, 2.0 * a_max, at * at))


def braking_constants(a_max: np.ndarray, period_s: float) -> tuple:
    """``(a T, 2 a, (a T)²)`` for :func:`_vp_box` (precomputed when ``a_max`` is constant)."""
    at = np.asarray(a_max, dtype=float) * period_s
    return at, 2.0 * np.asarray(a_max, dtype=float), at * at


def _vp_box(
    q: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    qd_max: np.ndarray,
    period_s: float,
    brake: tuple | None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`velocity_position_box` with the braking constants ``(a T, 2 a, (a T)²)`` given
    (or ``None``: no braking bound); the controllers' hot path."""
    # one stacked computation for both sides: row 0 is the upper bound, row 1 minus the
    # lower bound (the same floating-point operations as bounding each side separately)
    dist = np.empty((2,) + q.shape)
    np.subtract(q_max, q, out=dist[0])
    np.subtract(q, q_min, out=dist[1])
    side = dist / period_s
    np.minimum(side, qd_max, out=side)
    if brake is not None:
        at, two_a, at2 = brake
        speed = np.maximum(dist, 0.0, out=dist)  # braking_speed(), in place
        speed *= two_a
        speed += at2
        np.sqrt(speed, out=speed)
        speed -= at
        np.minimum(side, speed, out=side)
    hi = side[0]
    lo = np.negative(side[1])
    # beyond a limit the position bound asks for a return faster than the velocity bound
    # allows: the velocity bound wins (move back as fast as allowed)
    np.maximum(hi, np.minimum(lo, qd_max), out=hi)
    np.minimum(lo, hi, out=lo)
    return lo, hi


def command_box(
    q: np.ndarray,
    qd_prev: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    qd_max: np.ndarray,
    a_max: np.ndarray,
    period_s: float,
    braking_aware: bool = True,
) -> Box:
    """The admissible interval of the command applied now (docs/theory.md §5).

    Intersection of the velocity, position-through-one-period (optionally braking-aware)
    and acceleration bounds; where the acceleration bound conflicts with the others it is
    kept and the joint brakes as hard as it allows. The box is never empty.
    """
    lo_vp, hi_vp = velocity_position_box(
        q, q_min, q_max, qd_max, period_s, a_max if braking_aware else None
    )
    return intersect_acceleration(lo_vp, hi_vp, qd_prev, period_s * a_max)


def intersect_acceleration(
    lo_vp: np.ndarray, hi_vp: np.ndarray, qd_prev: np.ndarray, step: np.ndarray
) -> Box:
    """Intersect a velocity/position box with ``|qd - qd_prev| ≤ step`` (the conflict rule
    of :func:`command_box` where they do not meet)."""
    lo_a = qd_prev - step
    hi_a = qd_prev + step
    lo = np.maximum(lo_vp, lo_a)
    hi = np.minimum(hi_vp, hi_a)
    conflict = lo > hi
    if conflict.any():
        # closest point of [lo_a, hi_a] to [lo_vp, hi_vp]
        target = np.where(hi_a < lo_vp, hi_a, lo_a)
        lo = np.where(conflict, target, lo)
        hi = np.where(conflict, target, hi)
    return Box(lower=lo, upper=hi, conflict=conflict)


def safe_command(box: Box) -> np.ndarray:
    """The safest admissible command: the point of ``box`` closest to standing still.

    It decelerates towards zero as fast as the acceleration bound allows and respects every
    other bound the box holds (the fallback of docs/theory.md §5).
    """
    return box.project(np.zeros_like(box.lower))
