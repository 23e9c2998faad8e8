"""The bound box joint by joint on floats, compiled: the scalar twin of :mod:`bounds`.

The 1 kHz hot paths build the box of every joint in one compiled call, with the very
floating-point operations of :func:`~dqcontrol.controllers.bounds.command_box` (tests check
bit equality), because numpy's per-call cost on 7-element arrays exceeds the arithmetic:
:func:`joint_boxes` (the local controller's QP bounds and, with :func:`project`, the
proportional controller's clip) and :func:`vp_boxes` (the general step's bounds of every
instant). Far from its limits a joint's box is just ``±qd_max`` (:func:`joint_constants`
says how far is far); near them, :func:`near_limit_box`. Numba compiles them without
fast-math: the IEEE operations in the order written.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["joint_boxes", "joint_constants", "near_limit_box", "project", "vp_boxes"]


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


@compiled
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


@compiled
def joint_boxes(
    q: np.ndarray,
    qd_prev: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    consts: np.ndarray,
    period_s: float,
    braking: bool,
    bounds: np.ndarray,
    conflict: np.ndarray,
) -> int:
    """The command box of every joint, as ``bounds._vp_box`` + ``intersect_acceleration``.

    ``consts`` is :func:`joint_constants` as an ``(n, 6)`` array. Writes the box of joint
    ``j`` to ``bounds[0, j]`` / ``bounds[1, j]`` [rad/s] (``bounds`` is ``(2, ≥ n)``) and
    ``conflict[j]`` (1 where the acceleration interval misses the velocity/position box
    and the box collapses to its point closest to that box, else 0). Returns the number of
    conflicts, or -1 where the box is not usable as a QP's bounds (a NaN limit or previous
    command, a bound beyond ±1e30): the caller then takes its general path, which refuses
    such bounds.
    """
    count = 0
    for j in range(q.shape[0]):
        v_max, far, at, two_a, at2, step = (
            consts[j, 0], consts[j, 1], consts[j, 2], consts[j, 3], consts[j, 4], consts[j, 5]
        )  # fmt: skip
        prev = qd_prev[j]
        q_lo = q_min[j]
        q_hi = q_max[j]
        lo_a = prev - step  # the acceleration bound
        hi_a = prev + step
        d_hi = q_hi - q[j]
        d_lo = q[j] - q_lo
        if d_hi >= far and d_lo >= far:
            # far from both limits: the velocity bound (finite, v_max > 0)
            lo = -v_max
            hi = v_max
        else:
            lo, hi = near_limit_box(d_hi, d_lo, v_max, period_s, braking, at, two_a, at2)
        # ∩ acceleration, with its conflict rule: where they do not meet, the point of
        # the acceleration interval closest to the box
        lo_box = lo_a if lo_a > lo else lo
        hi_box = hi_a if hi_a < hi else hi
        conflict[j] = 0
        if lo_box > hi_box:
            lo_box = hi_box = hi_a if hi_a < lo else lo_a
            conflict[j] = 1
            count += 1
        # what DaqpQP.solve checks and clamps (a NaN limit or command fails here)
        if not (q_lo <= q_hi and prev == prev and -1e30 <= lo_box <= hi_box <= 1e30):
            return -1
        bounds[0, j] = lo_box
        bounds[1, j] = hi_box
    return count


@compiled
def project(qd: np.ndarray, bounds: np.ndarray, out: np.ndarray) -> bool:
    """``out = clip(qd, bounds[0], bounds[1])`` per joint (``Box.project``); whether any
    entry was clipped."""
    clipped = False
    for j in range(qd.shape[0]):
        v = qd[j]
        if v < bounds[0, j]:
            v = bounds[0, j]
            clipped = True
        elif v > bounds[1, j]:
            v = bounds[1, j]
            clipped = True
        out[j] = v
    return clipped


@compiled
def vp_boxes(
    q: np.ndarray,
    q_hat: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    qd_max: np.ndarray,
    period_s: float,
    braking: bool,
    at: np.ndarray,
    two_a: np.ndarray,
    at2: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> None:
    """The velocity/position (and braking) box of every instant and joint, as
    ``bounds._vp_box`` on ``q_box`` = ``q`` for instant 0 and ``q̂_i`` clipped to the
    limits for the others: written to ``lower``/``upper`` (p, n), bit for bit.

    ``at``, ``two_a``, ``at2`` (p, n) are the braking constants at each instant (unused,
    any values, when ``braking`` is False)."""
    for i in range(q_hat.shape[0]):
        for j in range(q_hat.shape[1]):
            if i == 0:
                qj = q[j]
            else:
                qj = q_hat[i, j]
                qj = q_min[j] if qj < q_min[j] else qj  # np.maximum(q̂, q_min) ...
                qj = q_max[j] if qj > q_max[j] else qj  # ... then np.minimum(·, q_max)
            lo, hi = near_limit_box(
                q_max[j] - qj, qj - q_min[j], qd_max[j], period_s, braking,
                at[i, j], two_a[i, j], at2[i, j],
            )  # fmt: skip
            lower[i, j] = lo
            upper[i, j] = hi
