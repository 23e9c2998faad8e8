"""The bound box of one joint on Python floats: the scalar twin of :mod:`bounds`.

The single-instant hot paths (the proportional controller's clip, the local controller's
QP bounds) build the box joint by joint on floats, with the very floating-point
operations of :func:`~dqcontrol.controllers.bounds.command_box` (tests check bit
equality), because at 1 kHz numpy's per-call cost on 7-element arrays exceeds the
arithmetic. Far from its limits a joint's box is just ``±qd_max`` (:func:`joint_constants`
says how far is far); near them, :func:`near_limit_box`.
"""

from __future__ import annotations

import math

__all__ = ["joint_constants", "near_limit_box"]


def joint_constants(
    limits: list[tuple[float, float, float, float]],
    qd_max: list[float],
    period_s: float,
    braking: bool,
) -> list[tuple[float, ...]]:
    """Per joint ``(qd_max, far, a T, 2 a, (a T)², T a)`` for the per-joint box, from
    ``limits``, per joint ``(a T, 2 a, (a T)², T a)``.

    ``far`` is a distance to a position limit from which neither the one-period position
    bound nor the braking bound is below ``qd_max``: with ``d ≥ far`` the computed
    ``d / T`` and ``-a T + sqrt((a T)² + 2 a d)`` are ``≥ qd_max``. It is 1e-6 (relative)
    beyond the exact crossing and then verified with the very floating-point operations of
    the box, which are monotone in ``d``, so that checking ``d = far`` covers every
    ``d ≥ far``; where the check fails, ``far = inf`` (never taken). Beyond ``far`` the
    box of that side is ``qd_max`` exactly, as the full computation gives.
    """
    rows = []
    for v, (at, two_a, at2, step) in zip(qd_max, limits, strict=True):
        reach = period_s * v  # d / T = v
        if braking:  # -a T + sqrt((a T)² + 2 a d) = v
            reach = max(reach, (v * v + 2.0 * v * at) / two_a)
        far = reach * (1.0 + 1e-6)
        ok = far / period_s >= v
        if braking:
            ok = ok and math.sqrt(far * two_a + at2) - at >= v
        if not (ok and math.isfinite(far)):
            far = math.inf
        rows.append((v, far, at, two_a, at2, step))
    return rows


def near_limit_box(
    d_hi: float,
    d_lo: float,
    v_max: float,
    period_s: float,
    braking: bool,
    at: float,
    two_a: float,
    at2: float,
) -> tuple[float, float]:
    """``(lo, hi)`` [rad/s] of one joint ``d_lo``/``d_hi`` [rad] from its limits: velocity,
    position through one period and (``braking``) the stop-before-the-limit bound, with
    the beyond-a-limit rule of ``bounds._vp_box`` — its operations, on floats."""
    hi = d_hi / period_s
    if hi > v_max:
        hi = v_max
    lo = d_lo / period_s
    if lo > v_max:
        lo = v_max
    if braking:
        speed = math.sqrt((d_hi if d_hi > 0.0 else 0.0) * two_a + at2) - at
        if speed < hi:
            hi = speed
        speed = math.sqrt((d_lo if d_lo > 0.0 else 0.0) * two_a + at2) - at
        if speed < lo:
            lo = speed
    lo = -lo
    if lo > hi:  # beyond a limit: hi = max(hi, min(lo, qd_max)); lo = min(lo, hi)
        back = lo if lo < v_max else v_max
        if back > hi:
            hi = back
        if hi < lo:
            lo = hi
    return lo, hi
