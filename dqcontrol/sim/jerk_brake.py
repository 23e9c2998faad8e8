"""The jerk-limited braking law that ends a stop's joint motion (docs/theory.md §8.12).

Under a jerk bound ``j̄`` a joint at velocity ``v`` stops without passing 0 when its
deceleration is ``a* = -sign(v) sqrt(2 j̄ |v|)``: turning ``a*`` back to 0 at ``j̄`` takes
``|a*|/j̄`` and covers exactly ``v``. So that the joint velocities keep their direction
(motion in the path's null space stays there while it fades), every joint brakes at the
same rate ``κ`` [1/s], ``a*_i = -κ u_i``, ``κ`` the smallest of ``sqrt(2 j̄_i/|u_i|)`` and
``ā_i/|u_i|``. The acceleration is steered towards ``a*`` as fast as the jerk allows:

    a_0 = clip(a*, a_1 - j̄ T, a_1 + j̄ T) clipped to [-ā, ā],   u_next = u_1 + T a_0,

with ``u_1`` the last command and ``a_1 = (u_1 - u_2)/T``: every command keeps the
acceleration and jerk bounds.
"""

from __future__ import annotations

import numpy as np

__all__ = ["jerk_brake_command"]


def jerk_brake_command(
    u1: np.ndarray, u2: np.ndarray, a_max: np.ndarray, jerk: np.ndarray, period_s: float
) -> np.ndarray:
    """The next command [rad/s] of the braking law from the last two commands ``u1``,
    ``u2`` [rad/s] under ``a_max`` [rad/s²] and ``jerk`` [rad/s³] per joint (``inf``: no
    jerk bound)."""
    t = period_s
    a1 = (u1 - u2) / t
    speed = np.abs(u1)
    moving = speed > 0.0
    if not np.any(moving):
        rate = 0.0
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.minimum(np.sqrt(2.0 * jerk / speed), a_max / speed)
        rate = float(np.min(ratio[moving]))
    target = -rate * u1
    step = jerk * t
    a0 = np.where(np.isfinite(step), np.clip(target, a1 - step, a1 + step), target)
    return u1 + t * np.clip(a0, -a_max, a_max)
