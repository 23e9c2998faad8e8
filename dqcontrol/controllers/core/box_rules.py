"""The bound box joint by joint on floats, compiled: the kernels of the joint limits.

One implementation of each bound rule of docs/theory.md §5, used by every controller: the
velocity/position/braking box of one joint (:func:`near_limit_box`) and the intersection
with the acceleration interval under the conflict rule (:func:`intersect_hard`). The QP
controllers' limits write them straight into the QP's bound vectors
(:func:`applied_box_into`, :func:`predicted_boxes_into`, :func:`hard_interval_into`, the two
first ones in one pass: :func:`command_box_into`; the generic merge of any limit's bounds:
:func:`intersect_into`, :func:`hard_into`); the
proportional controller's clip takes the applied box of every joint in one call
(:func:`joint_boxes`, with :func:`joint_constants` saying how far from a limit a joint's
box is just ``±qd_max``). :mod:`~dqcontrol.controllers.core.bounds` computes the same numbers
with numpy (the tests' reference, bit for bit). Numba compiles them without fast-math: the
IEEE operations in the order written; minima and maxima propagate NaN as numpy's do.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol._compiled import compiled

__all__ = [
    "applied_box_into",
    "clip_solution",
    "command_box_into",
    "hard_interval_into",
    "hard_into",
    "intersect_hard",
    "intersect_into",
    "joint_boxes",
    "joint_constants",
    "near_limit_box",
    "predicted_boxes_into",
    "project",
]


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
    rows: list[tuple[float, ...]] = []
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
        # ∩ acceleration, with its conflict rule
        lo_box, hi_box, clash = intersect_hard(lo, hi, lo_a, hi_a)
        conflict[j] = 1 if clash else 0
        count += 1 if clash else 0
        # what a QP backend checks and clamps (a NaN limit or command fails here)
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
def _max(a: float, b: float) -> float:
    """``np.maximum(a, b)``: NaN if either is."""
    if a != a or b != b:
        return math.nan
    return a if a > b else b


@compiled
def _min(a: float, b: float) -> float:
    """``np.minimum(a, b)``: NaN if either is."""
    if a != a or b != b:
        return math.nan
    return a if a < b else b


@compiled
def intersect_hard(lo: float, hi: float, lo_h: float, hi_h: float) -> tuple[float, float, bool]:
    """``[lo, hi] ∩ [lo_h, hi_h]`` where the second interval is *hard* (the acceleration
    bound): where they do not meet, the point of ``[lo_h, hi_h]`` closest to ``[lo, hi]``
    (the conflict rule). Returns ``(lower, upper, conflict)``."""
    lo_box = _max(lo, lo_h)
    hi_box = _min(hi, hi_h)
    if lo_box > hi_box:
        target = hi_h if hi_h < lo else lo_h
        return target, target, True
    return lo_box, hi_box, False


@compiled
def intersect_into(
    lower: np.ndarray, upper: np.ndarray, index: np.ndarray, lo: np.ndarray, up: np.ndarray
) -> None:
    """``lower[index] = max(lower[index], lo)``, ``upper[index] = min(upper[index], up)``
    in place (a soft bound merged)."""
    for e in range(index.shape[0]):
        k = index[e]
        lower[k] = _max(lower[k], lo[e])
        upper[k] = _min(upper[k], up[e])


@compiled
def hard_into(
    lower: np.ndarray,
    upper: np.ndarray,
    conflict: np.ndarray,
    index: np.ndarray,
    lo_h: np.ndarray,
    up_h: np.ndarray,
) -> int:
    """A hard bound merged in place with the conflict rule (:func:`intersect_hard`);
    ``conflict[index]`` set where it applied. Returns the number of conflicts."""
    count = 0
    for e in range(index.shape[0]):
        k = index[e]
        lo, hi, clash = intersect_hard(lower[k], upper[k], lo_h[e], up_h[e])
        lower[k] = lo
        upper[k] = hi
        if clash:
            conflict[k] = 1
            count += 1
    return count


@compiled
def hard_interval_into(
    lower: np.ndarray,
    upper: np.ndarray,
    conflict: np.ndarray,
    index: np.ndarray,
    centre: np.ndarray,
    half_width: np.ndarray,
) -> int:
    """:func:`hard_into` with the hard interval ``centre ± half_width`` (the acceleration
    bound ``qd_prev ± T a_max``). Returns the number of conflicts."""
    count = 0
    for e in range(index.shape[0]):
        k = index[e]
        lo, hi, clash = intersect_hard(
            lower[k], upper[k], centre[e] - half_width[e], centre[e] + half_width[e]
        )
        lower[k] = lo
        upper[k] = hi
        if clash:
            conflict[k] = 1
            count += 1
    return count


@compiled
def braking_rows(a: np.ndarray, period_s: float) -> np.ndarray:
    """``[a T; 2 a; (a T)²]`` ``(3, n)`` of the bound ``a`` [rad/s²] (the braking constants
    of :func:`applied_box_into`)."""
    out = np.empty((3, a.shape[0]))
    for j in range(a.shape[0]):
        at = a[j] * period_s
        out[0, j] = at
        out[1, j] = 2.0 * a[j]
        out[2, j] = at * at
    return out


@compiled
def applied_box_into(
    q: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    qd_max: np.ndarray,
    period_s: float,
    braking: bool,
    brake: np.ndarray,
    index: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> None:
    """The box of the command applied now, from the measured ``q`` (n,), merged into
    ``lower``/``upper`` at ``index`` (n,) (``bounds.velocity_position_box`` on ``q``).
    ``brake`` (3, n) holds the braking constants ``a T``, ``2 a``, ``(a T)²`` (unused when
    ``braking`` is False)."""
    for j in range(q.shape[0]):
        qj = q[j]
        lo, hi = near_limit_box(
            q_max[j] - qj, qj - q_min[j], qd_max[j], period_s, braking,
            brake[0, j], brake[1, j], brake[2, j],
        )  # fmt: skip
        k = index[j]
        lower[k] = _max(lower[k], lo)
        upper[k] = _min(upper[k], hi)


@compiled
def command_box_into(
    q: np.ndarray,
    qd_prev: np.ndarray,
    values: np.ndarray,
    a_max: np.ndarray,
    period_s: float,
    braking: bool,
    lower: np.ndarray,
    upper: np.ndarray,
    conflict: np.ndarray,
) -> int:
    """The command box of the applied block merged into ``lower``/``upper`` in place, joint
    by joint: :func:`applied_box_into` at the measured ``q`` (n,), then the hard acceleration
    interval ``qd_prev ± T a`` with the conflict rule (:func:`hard_interval_into`).

    ``values`` is ``[q_min; q_max; qd_max]`` (3, n), ``a_max[0]`` the applied block's
    ``a`` (the braking constants ``a T``, ``2 a``, ``(a T)²`` are formed here as
    ``bounds.braking_constants`` forms them). Joint ``j``'s command is entry ``j`` of the
    bounds (the applied block comes first); ``conflict[j]`` is set where the rule applied.
    Returns the number of conflicts."""
    count = 0
    for j in range(q.shape[0]):
        qj = q[j]
        a = a_max[0, j]
        at = a * period_s
        lo, hi = near_limit_box(
            values[1, j] - qj, qj - values[0, j], values[2, j], period_s, braking, at,
            2.0 * a, at * at,
        )  # fmt: skip
        prev = qd_prev[j]
        lo, hi, clash = intersect_hard(_max(lower[j], lo), _min(upper[j], hi), prev - at, prev + at)
        lower[j] = lo
        upper[j] = hi
        if clash:
            conflict[j] = 1
            count += 1
    return count


@compiled
def predicted_boxes_into(
    q_hat: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    qd_max: np.ndarray,
    period_s: float,
    braking: bool,
    brake: np.ndarray,
    index: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> None:
    """The boxes of the predicted blocks ``i ≥ 1``, each at ``q̂_i`` clipped to the limits
    (``bounds.velocity_position_box`` on ``clip(q̂_i)``), merged into ``lower``/``upper`` at
    ``index[i]`` (``q_hat`` and ``index`` are ``(p, n)``, the braking constants ``brake``
    ``(3, p, n)``; row 0 is not read)."""
    for i in range(1, q_hat.shape[0]):
        for j in range(q_hat.shape[1]):
            qj = q_hat[i, j]
            qj = q_min[j] if qj < q_min[j] else qj  # np.maximum(q̂, q_min) ...
            qj = q_max[j] if qj > q_max[j] else qj  # ... then np.minimum(·, q_max)
            lo, hi = near_limit_box(
                q_max[j] - qj, qj - q_min[j], qd_max[j], period_s, braking,
                brake[0, i, j], brake[1, i, j], brake[2, i, j],
            )  # fmt: skip
            k = index[i, j]
            lower[k] = _max(lower[k], lo)
            upper[k] = _min(upper[k], hi)


@compiled
def clip_solution(
    z: np.ndarray, lower: np.ndarray, upper: np.ndarray, n: int, s_at: int, s_max: float
) -> float:
    """Apply a QP's solution: ``z[:n]`` (the applied command) clipped to its bounds in place,
    all of ``z`` when it has one bound per entry (one block, no general row); numpy's
    ``minimum(maximum(·))``, NaN included. Returns the applied time scaling read before the
    clip, ``min(max(z[s_at], 0), s_max)`` (Python's ``min`` and ``max``), or 1 when
    ``s_at < 0`` (no scaling)."""
    s = 1.0
    if s_at >= 0:
        s = z[s_at]
        if 0.0 > s:
            s = 0.0
        if s_max < s:
            s = s_max
    count = z.shape[0] if z.shape[0] == lower.shape[0] else n
    for k in range(count):
        z[k] = _min(_max(z[k], lower[k]), upper[k])
    return s
