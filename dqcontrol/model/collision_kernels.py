"""Compiled kernels of the collision queries: the kinematics of a batch of configurations, the
capsule lower bounds of every pair's distance, and the distance gradients.

Each works on a handful of small arrays per configuration, where numpy's per-call cost would
be most of the time; they are written out on floats and compiled with Numba.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.model.collision_closed_forms import solve_closed_forms

__all__ = [
    "FAILED_DISTANCE_M",
    "SEPARATED_M",
    "capsule_gaps",
    "chain_kinematics",
    "close_pairs",
    "collect_pairs",
    "distance_gradients",
    "screen_pairs",
    "segment_distance",
]

#: Below this ``sin²`` of the angle between two segments they are taken as parallel.
_PARALLEL_SIN2 = 1e-12

#: A distance below this [m] is coal's sign that the penetration solver (EPA) failed (it
#: returns ``-DBL_MAX`` on some deep penetrations); such a pair is reported at ``-inf`` with
#: NaN witness points and normal and a zero gradient.
FAILED_DISTANCE_M = -1e3

#: Shapes further apart than this [m] take their normal from the witness points.
SEPARATED_M = 1e-6


@compiled
def chain_kinematics(
    qs: np.ndarray,
    parents: np.ndarray,
    rotations: np.ndarray,
    shifts: np.ndarray,
    k1: np.ndarray,
    k2: np.ndarray,
    axes: np.ndarray,
    iq: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint placements and world Jacobians of a chain of 1-DoF revolute joints.

    For every configuration ``i`` and joint ``j``: ``R_j = R_parent (R_p + sin q K_p +
    (1 - cos q) K²_p)``, ``t_j = R_parent t_p + t_parent``, and joint ``j``'s Jacobian column
    ``[t_j × ω_j; ω_j]`` with ``ω_j = R_j a_j`` (Pinocchio's ``data.J``). Returns ``rot``
    ``(N, njoints, 3, 3)``, ``trans`` ``(N, njoints, 3)`` and ``jac`` ``(N, 6, n)``; joint 0
    is the world (identity)."""
    nj = rotations.shape[0]
    rot = np.empty((qs.shape[0], nj, 3, 3))
    trans = np.empty((qs.shape[0], nj, 3))
    jac = np.zeros((qs.shape[0], 6, qs.shape[1]))
    for i in range(qs.shape[0]):
        rot[i, 0] = 0.0
        trans[i, 0] = 0.0
        for r in range(3):
            rot[i, 0, r, r] = 1.0
        for j in range(1, nj):
            p = parents[j]
            angle = qs[i, iq[j]]
            s, c1 = math.sin(angle), 1.0 - math.cos(angle)
            for r in range(3):
                for c in range(3):
                    acc = 0.0
                    for m in range(3):
                        local = rotations[j, m, c] + s * k1[j, m, c] + c1 * k2[j, m, c]
                        acc += rot[i, p, r, m] * local
                    rot[i, j, r, c] = acc
                acc = trans[i, p, r]
                for m in range(3):
                    acc += rot[i, p, r, m] * shifts[j, m]
                trans[i, j, r] = acc
            w0 = rot[i, j, 0, 0] * axes[j, 0] + rot[i, j, 0, 1] * axes[j, 1]
            w0 += rot[i, j, 0, 2] * axes[j, 2]
            w1 = rot[i, j, 1, 0] * axes[j, 0] + rot[i, j, 1, 1] * axes[j, 1]
            w1 += rot[i, j, 1, 2] * axes[j, 2]
            w2 = rot[i, j, 2, 0] * axes[j, 0] + rot[i, j, 2, 1] * axes[j, 1]
            w2 += rot[i, j, 2, 2] * axes[j, 2]
            t0, t1, t2 = trans[i, j, 0], trans[i, j, 1], trans[i, j, 2]
            col = iq[j]
            jac[i, 0, col] = t1 * w2 - t2 * w1
            jac[i, 1, col] = t2 * w0 - t0 * w2
            jac[i, 2, col] = t0 * w1 - t1 * w0
            jac[i, 3, col] = w0
            jac[i, 4, col] = w1
            jac[i, 5, col] = w2
    return rot, trans, jac


@compiled
def segment_distance(
    ends: np.ndarray, first: int, second: int
) -> tuple[float, float, float, float]:
    """The distance [m] between the segments ``ends[first]`` and ``ends[second]`` (each
    ``(2, 3)``: its two ends), less a rounding allowance so that it is never above the exact
    distance, and the vector from the second segment's nearest point to the first's
    (Ericson, *Real-Time Collision Detection*, §5.1.9).

    Segments within ``1e-6`` rad of parallel are solved as parallel (one end's parameter set
    to 0, the other clamped, then the first re-clamped): the distance is then off by at most
    the angle times the segment's length, which the allowance covers, as it covers the
    rounding of the general case."""
    p1x, p1y, p1z = ends[first, 0, 0], ends[first, 0, 1], ends[first, 0, 2]
    p2x, p2y, p2z = ends[second, 0, 0], ends[second, 0, 1], ends[second, 0, 2]
    d1x, d1y, d1z = ends[first, 1, 0] - p1x, ends[first, 1, 1] - p1y, ends[first, 1, 2] - p1z
    d2x, d2y, d2z = ends[second, 1, 0] - p2x, ends[second, 1, 1] - p2y, ends[second, 1, 2] - p2z
    rx, ry, rz = p1x - p2x, p1y - p2y, p1z - p2z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    s, t = 0.0, 0.0
    if a > 0.0 or e > 0.0:
        if a == 0.0:
            t = min(max(f / e, 0.0), 1.0)
        else:
            c = d1x * rx + d1y * ry + d1z * rz
            if e == 0.0:
                s = min(max(-c / a, 0.0), 1.0)
            else:
                b = d1x * d2x + d1y * d2y + d1z * d2z
                denom = a * e - b * b
                if denom > _PARALLEL_SIN2 * a * e:
                    s = min(max((b * f - c * e) / denom, 0.0), 1.0)
                t = (b * s + f) / e
                if t < 0.0:
                    t = 0.0
                    s = min(max(-c / a, 0.0), 1.0)
                elif t > 1.0:
                    t = 1.0
                    s = min(max((b - c) / a, 0.0), 1.0)
    gx = rx + s * d1x - t * d2x
    gy = ry + s * d1y - t * d2y
    gz = rz + s * d1z - t * d2z
    allowance = 1e-9 + 1e-6 * (math.sqrt(a) + math.sqrt(e))
    return math.sqrt(gx * gx + gy * gy + gz * gz) - allowance, gx, gy, gz


#: Columns of a shape's support form (:func:`support`): centre, three half-spans, disc axis,
#: disc radius, ball radius.
FORM_SIZE = 17


@compiled
def support(forms: np.ndarray, g: int, ux: float, uy: float, uz: float) -> float:
    """Shape ``g``'s support ``h(u) = uᵀc + Σ_i |uᵀs_i| + ρ √(1 - (uᵀa)²) + r`` [m] along the
    unit ``u``; ``forms[g]``: ``c, s_0, s_1, s_2, a, ρ, r`` in the world
    (:func:`~dqcontrol.model.collision_bounds.support_form`)."""
    h = ux * forms[g, 0] + uy * forms[g, 1] + uz * forms[g, 2] + forms[g, 16]
    for i in range(3, 12, 3):
        h += abs(ux * forms[g, i] + uy * forms[g, i + 1] + uz * forms[g, i + 2])
    if forms[g, 15] > 0.0:
        along = ux * forms[g, 12] + uy * forms[g, 13] + uz * forms[g, 14]
        h += forms[g, 15] * math.sqrt(max(1.0 - along * along, 0.0))
    return h


@compiled
def separation(forms: np.ndarray, a: int, b: int, vx: float, vy: float, vz: float) -> float:
    """``-h_b(-u) - h_a(u)`` [m] with ``u = v/|v|`` (from ``a`` towards ``b``): a lower
    bound of the shapes' distance, less a rounding allowance (``-inf`` for a zero ``v``)."""
    norm = math.sqrt(vx * vx + vy * vy + vz * vz)
    if not norm > 1e-12:
        return -np.inf
    ux, uy, uz = vx / norm, vy / norm, vz / norm
    return -support(forms, b, -ux, -uy, -uz) - support(forms, a, ux, uy, uz) - 1e-9


@compiled
def _place_shapes(
    rot: np.ndarray,
    trans: np.ndarray,
    joint_of: np.ndarray,
    ends: np.ndarray,
    forms_local: np.ndarray,
    ends_w: np.ndarray,
    forms: np.ndarray,
    mids: np.ndarray,
) -> None:
    """The capsules' ends ``ends_w`` ``(g, 2, 3)``, their middles ``mids`` ``(g, 3)`` and
    the support forms ``forms`` ``(g, 17)`` in the world, from those in the joints' frames
    and one configuration's joint placements ``rot`` ``(njoints, 3, 3)``, ``trans``
    ``(njoints, 3)``: the centre and the ends are points, the half-spans and the disc axis
    directions; the radii are kept."""
    for g in range(ends.shape[0]):
        j = joint_of[g]
        for r in range(3):
            r0, r1, r2 = rot[j, r, 0], rot[j, r, 1], rot[j, r, 2]
            for e in range(2):
                ends_w[g, e, r] = trans[j, r] + (
                    r0 * ends[g, e, 0] + r1 * ends[g, e, 1] + r2 * ends[g, e, 2]
                )
            mids[g, r] = 0.5 * (ends_w[g, 0, r] + ends_w[g, 1, r])
            for v in range(5):  # centre, three half-spans, disc axis
                c = 3 * v
                x = r0 * forms_local[g, c] + r1 * forms_local[g, c + 1]
                x += r2 * forms_local[g, c + 2]
                forms[g, c + r] = x + trans[j, r] if v == 0 else x
        forms[g, 15], forms[g, 16] = forms_local[g, 15], forms_local[g, 16]


@compiled
def _ball_radii(ends: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """The radius [m] of the ball around each capsule's middle that holds it: half its
    segment's length and its radius, and :func:`segment_distance`'s rounding allowance, so
    that the balls' gap is never above the capsules' one."""
    out = np.empty(radii.shape[0])
    for g in range(radii.shape[0]):
        dx, dy = ends[g, 1, 0] - ends[g, 0, 0], ends[g, 1, 1] - ends[g, 0, 1]
        dz = ends[g, 1, 2] - ends[g, 0, 2]
        half = 0.5 * math.sqrt(dx * dx + dy * dy + dz * dz)
        out[g] = half + radii[g] + 1e-9 + 2e-6 * half
    return out


@compiled
def capsule_gaps(
    rot: np.ndarray,
    trans: np.ndarray,
    joint_of: np.ndarray,
    ends: np.ndarray,
    radii: np.ndarray,
    forms_local: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
    plane_normals: np.ndarray,
    plane_offsets: np.ndarray,
    is_plane: np.ndarray,
    influence_m: float,
) -> np.ndarray:
    """Lower bounds of every pair's distance ``(N, pairs)`` [m] from the joint placements
    ``rot`` ``(N, njoints, 3, 3)``, ``trans`` ``(N, njoints, 3)``.

    Shape ``g`` is inside the capsule of radius ``radii[g]`` around the segment ``ends[g]``
    ``(2, 3)`` in the frame of joint ``joint_of[g]``, with the support function
    ``forms_local[g]`` there (:func:`support`), and inside the ball around the segment's
    middle (:func:`_ball_radii`). A pair ``(first[p], second[p])`` is at least the largest
    of: its capsules' distance and the support gaps along the segments' nearest points and
    along the centres, tried in turn until one reaches ``influence_m``. A half-space
    ``second[p]`` (``is_plane``: ``{x : nᵀx ≤ offset}``) is exactly ``-h(-n) - offset``
    away. Pairs whose bounding balls are further apart than ``influence_m`` take the balls'
    distance."""
    count, shapes, pairs = rot.shape[0], ends.shape[0], first.shape[0]
    ends_w, mids = np.empty((shapes, 2, 3)), np.empty((shapes, 3))
    forms = np.empty((shapes, FORM_SIZE))
    out = np.empty((count, pairs))
    reach = _ball_radii(ends, radii)
    for i in range(count):
        _place_shapes(rot[i], trans[i], joint_of, ends, forms_local, ends_w, forms, mids)
        for p in range(pairs):
            a, b = first[p], second[p]
            if is_plane[b]:
                nx, ny, nz = plane_normals[b, 0], plane_normals[b, 1], plane_normals[b, 2]
                gap = nx * mids[a, 0] + ny * mids[a, 1] + nz * mids[a, 2] - reach[a]
                out[i, p] = gap - plane_offsets[b] - 1e-9
                if out[i, p] < influence_m:
                    out[i, p] = -support(forms, a, -nx, -ny, -nz) - plane_offsets[b] - 1e-9
                continue
            cx, cy, cz = mids[a, 0] - mids[b, 0], mids[a, 1] - mids[b, 1], mids[a, 2] - mids[b, 2]
            out[i, p] = best = math.sqrt(cx * cx + cy * cy + cz * cz) - reach[a] - reach[b]
            if best >= influence_m:
                continue
            gap, gx, gy, gz = segment_distance(ends_w, a, b)
            out[i, p] = best = gap - radii[a] - radii[b]
            if best >= influence_m:
                continue
            out[i, p] = best = max(best, separation(forms, a, b, -gx, -gy, -gz))
            if best >= influence_m:
                continue
            cx, cy, cz = (
                forms[b, 0] - forms[a, 0],
                forms[b, 1] - forms[a, 1],
                forms[b, 2] - forms[a, 2],
            )
            out[i, p] = max(best, separation(forms, a, b, cx, cy, cz))
    return out


@compiled
def distance_gradients(
    state: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
    point_a: np.ndarray,
    point_b: np.ndarray,
    normal: np.ndarray,
    jac: np.ndarray,
    support: np.ndarray,
    joint_of: np.ndarray,
) -> np.ndarray:
    """``∇d = (J_b(p_b) - J_a(p_a))ᵀ n`` ``(k, n)`` [m/rad] of ``k`` pairs of shapes
    ``(first, second)`` at configurations ``state``, with witness points ``point_a``,
    ``point_b`` and normals ``normal`` ``(k, 3)``.

    With the world Jacobian ``[J_v; J_ω]`` of configuration ``state[k]`` ``jac`` ``(N, 6,
    n)``, a body point at ``p`` moves at ``J_v q̇ + J_ω q̇ × p`` on the columns of the joints
    that carry the body (``support`` ``(njoints, n)``, 1 there), so ``nᵀ J_p = nᵀ J_v +
    (p × n)ᵀ J_ω`` on those columns. A non-finite normal (a failed query) gives zero."""
    k_count, n = first.shape[0], jac.shape[2]
    out = np.zeros((k_count, n))
    for k in range(k_count):
        nx, ny, nz = normal[k, 0], normal[k, 1], normal[k, 2]
        if not (math.isfinite(nx) and math.isfinite(ny) and math.isfinite(nz)):
            continue
        i = state[k]
        ax, ay, az = point_a[k, 0], point_a[k, 1], point_a[k, 2]
        bx, by, bz = point_b[k, 0], point_b[k, 1], point_b[k, 2]
        # p × n for both points
        cax, cay, caz = ay * nz - az * ny, az * nx - ax * nz, ax * ny - ay * nx
        cbx, cby, cbz = by * nz - bz * ny, bz * nx - bx * nz, bx * ny - by * nx
        sa, sb = support[joint_of[first[k]]], support[joint_of[second[k]]]
        for c in range(n):
            nv = nx * jac[i, 0, c] + ny * jac[i, 1, c] + nz * jac[i, 2, c]
            wa = cax * jac[i, 3, c] + cay * jac[i, 4, c] + caz * jac[i, 5, c]
            wb = cbx * jac[i, 3, c] + cby * jac[i, 4, c] + cbz * jac[i, 5, c]
            out[k, c] = (nv + wb) * sb[c] - (nv + wa) * sa[c]
    return out


@compiled
def close_pairs(
    gaps: np.ndarray,
    qs: np.ndarray,
    reference_q: np.ndarray,
    reference_m: np.ndarray,
    levers_m: np.ndarray,
    influence_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The configurations and pairs ``(k,)``, ``(k,)`` (by configuration, then pair) whose
    lower bounds ``gaps`` ``(N, pairs)`` [m] and whose motion bounds are both below
    ``influence_m``.

    Pair ``p`` was ``reference_m[p]`` apart at ``reference_q[p]`` (``-inf``: unknown). Turning
    joint ``c`` by ``Δq_c`` moves no point of the pair's shapes, relative to the other shape,
    by more than ``levers_m[p, c] |Δq_c|``, so the distance at ``qs[i]`` is at least
    ``reference_m[p] - Σ_c levers_m[p, c] |qs[i, c] - reference_q[p, c]|`` (less an allowance
    for the reference's solver tolerance)."""
    count, pairs, n = qs.shape[0], gaps.shape[1], qs.shape[1]
    states = np.empty(count * pairs, dtype=np.int64)
    found = np.empty(count * pairs, dtype=np.int64)
    k = 0
    for i in range(count):
        for p in range(pairs):
            if not gaps[i, p] < influence_m:
                continue
            bound = reference_m[p] - 1e-6
            if bound >= influence_m:
                for c in range(n):
                    bound -= levers_m[p, c] * abs(qs[i, c] - reference_q[p, c])
                if bound >= influence_m:
                    continue
            states[k], found[k] = i, p
            k += 1
    return states[:k], found[:k]


@compiled
def screen_pairs(
    rot: np.ndarray,
    trans: np.ndarray,
    qs: np.ndarray,
    joint_of: np.ndarray,
    ends: np.ndarray,
    radii: np.ndarray,
    forms_local: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
    plane_normals: np.ndarray,
    plane_offsets: np.ndarray,
    is_plane: np.ndarray,
    reference_q: np.ndarray,
    reference_m: np.ndarray,
    levers_m: np.ndarray,
    kind: np.ndarray,
    swapped: np.ndarray,
    local_rot: np.ndarray,
    local_trans: np.ndarray,
    size: np.ndarray,
    influence_m: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pairs that may be within ``influence_m`` [m] at each configuration of ``qs``
    (:func:`capsule_gaps`, then :func:`close_pairs`; the arguments are theirs), solved
    where a closed form exists (``kind`` … ``size``: the tables of
    :func:`~dqcontrol.model.collision_closed_forms.solve_closed_forms`): configuration
    ``(K,)``, pair ``(K,)``, distance ``(K,)``, points ``(K, 3, 3)`` and the ones left for
    coal ``(k, 3)``: index ``m``, configuration, pair."""
    gaps = capsule_gaps(
        rot, trans, joint_of, ends, radii, forms_local, first, second, plane_normals,
        plane_offsets, is_plane, influence_m,
    )  # fmt: skip
    states, pairs = close_pairs(gaps, qs, reference_q, reference_m, levers_m, influence_m)
    solved, points, todo = solve_closed_forms(
        rot, trans, states, pairs, first, second, joint_of, kind, swapped, local_rot,
        local_trans, size,
    )  # fmt: skip
    jobs = np.empty((todo.shape[0], 3), dtype=np.int64)
    for r in range(todo.shape[0]):
        jobs[r, 0], jobs[r, 1], jobs[r, 2] = todo[r], states[todo[r]], pairs[todo[r]]
    return states, pairs, solved, points, jobs


@compiled
def collect_pairs(
    qs: np.ndarray,
    states: np.ndarray,
    pairs: np.ndarray,
    solved_m: np.ndarray,
    influence_m: float,
    points: np.ndarray,
    jac: np.ndarray,
    support: np.ndarray,
    joint_of: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
    reference_q: np.ndarray,
    reference_m: np.ndarray,
    remember: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pairs found close from the distances solved for ``(states[m], pairs[m])``
    (``solved_m`` ``(K,)``, witness points ``a``, ``b`` and normal ``points`` ``(K, 3, 3)``
    in coal's conventions), those below ``influence_m`` [m]: configuration, pair, distance,
    points (with the separation normal) and gradients ``(k, n)``.

    A failed query (below :data:`FAILED_DISTANCE_M`) is reported at ``-inf`` with NaN points
    and a zero gradient. Where the shapes are apart (``d > SEPARATED_M``) the normal is
    ``(p_b - p_a)/d``: the direction in which the distance grows, whichever witness points
    GJK chose on parallel faces; coal's normal where they touch or overlap. With
    ``remember``, each solved pair's distance and configuration become its reference
    (:func:`close_pairs`; a failed one unknown, ``-inf``)."""
    hits = np.flatnonzero(solved_m < influence_m)
    count = hits.shape[0]
    state = np.empty(count, dtype=np.int64)
    pair = np.empty(count, dtype=np.int64)
    distance = np.empty(count)
    out = np.empty((count, 3, 3))
    for k in range(count):
        m = hits[k]
        for i in range(3):  # entry by entry: a slice assignment compiles NumPy's shape
            for j in range(3):  # checks and their messages, seconds of compilation
                out[k, i, j] = points[m, i, j]
        state[k], pair[k] = states[m], pairs[m]
        d = solved_m[m]
        if not d > FAILED_DISTANCE_M:
            d = -np.inf
            out[k] = np.nan
        elif d > SEPARATED_M:
            for r in range(3):
                out[k, 2, r] = (out[k, 1, r] - out[k, 0, r]) / d
        distance[k] = d
    grads = distance_gradients(
        state, first[pair], second[pair], out[:, 0], out[:, 1], out[:, 2], jac, support, joint_of
    )
    if remember:
        for m in range(states.shape[0]):  # in order: the last configuration stays
            d = solved_m[m]
            reference_m[pairs[m]] = d if d > FAILED_DISTANCE_M else -np.inf
            for j in range(qs.shape[1]):
                reference_q[pairs[m], j] = qs[states[m], j]
    return state, pair, distance, out, grads
