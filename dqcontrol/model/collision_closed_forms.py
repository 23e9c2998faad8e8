"""Exact distances of the shape pairs that have a closed form, in coal's conventions.

A sphere against a sphere, a cylinder, a box or a half-space, and a cylinder against a
half-space, have their distance, witness points and normal in a few dozen flops; the
compiled :func:`solve_closed_forms` computes them from the batch's joint placements, so that
such pairs need neither coal nor Pinocchio's placement of the shapes. Every other pair stays
on coal.

The results are coal's for the same pair, in penetration too: coal solves these pairs by the
same formulas rather than by GJK/EPA. Signed distance ``d``, witness points ``p_a`` on ``a``
and ``p_b`` on ``b`` with ``p_b - p_a = d n``, unit normal ``n`` from ``a`` to ``b``:

- sphere–sphere: along the centres' line (``x`` where the centres coincide);
- sphere–cylinder: a centre beside the cylinder (its projection on the axis within the
  length) is pushed out radially, through the side, even where a cap is nearer; beyond a
  cap, the nearest point is on the cap's disc or on its rim. A centre on the axis has no
  radial direction: the normal is zero there, as coal reports it;
- sphere–box: the nearest point of the box; a centre inside leaves through the nearest face;
- sphere or cylinder against a half-space: the shape's deepest point along the plane's
  normal (the disc's centre where the cylinder's axis is within ``1e-12`` of it, the middle
  of the side where it is that close to the plane) and its projection on the plane.

A pair stored in the other order (the cylinder, box or half-space first) swaps the points
and reverses the normal.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import coal
import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["ClosedForms", "closed_form_table", "solve_closed_forms"]

#: Pair kinds (the first shape named first); 0: solved by coal.
COAL, SPHERE_SPHERE, SPHERE_CYLINDER, SPHERE_BOX, SPHERE_HALFSPACE, CYLINDER_HALFSPACE = range(6)

_KINDS = {
    ("sphere", "sphere"): SPHERE_SPHERE,
    ("sphere", "cylinder"): SPHERE_CYLINDER,
    ("sphere", "box"): SPHERE_BOX,
    ("sphere", "halfspace"): SPHERE_HALFSPACE,
    ("cylinder", "halfspace"): CYLINDER_HALFSPACE,
}

#: Coincident sphere centres below this [m] (coal's: the machine epsilon).
_CENTRES_M = float(np.finfo(float).eps)
#: A sphere centre this close to a cylinder's axis [m] has no radial direction.
_AXIS_M = math.sqrt(_CENTRES_M)
#: A direction within this of a cylinder's axis (or of its plane) is taken as along it.
_ALIGNED = 1e-12


class ClosedForms(NamedTuple):
    """The closed-form pairs of a geometry model.

    Attributes:
        kind: each pair's kind ``(pairs,)`` (:data:`COAL` where coal solves it).
        swapped: the pair's ``b`` is the kind's first shape ``(pairs,)``.
        rotation: each shape's rotation in its joint's frame ``(g, 3, 3)``.
        translation: each shape's position in its joint's frame [m] ``(g, 3)``.
        size: a sphere's radius, a cylinder's radius and half-length, a box's half sides,
            a half-space's normal and offset (in the shape's frame) ``(g, 4)``.
    """

    kind: np.ndarray
    swapped: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    size: np.ndarray


def _shape_kind(shape: coal.ShapeBase) -> tuple[str, list[float]]:
    """The shape's name and sizes as :class:`ClosedForms` holds them (``""``: none)."""
    if shape.getSweptSphereRadius() != 0.0:
        return "", []
    if isinstance(shape, coal.Sphere):
        return "sphere", [float(shape.radius)]
    if isinstance(shape, coal.Cylinder):
        return "cylinder", [float(shape.radius), float(shape.halfLength)]
    if isinstance(shape, coal.Box):
        return "box", [float(v) for v in shape.halfSide]
    if isinstance(shape, coal.Halfspace):
        return "halfspace", [*(float(v) for v in shape.n), float(shape.d)]
    return "", []


def closed_form_table(geometry, first: np.ndarray, second: np.ndarray) -> ClosedForms:
    """The kinds of the pairs ``(first[p], second[p])`` of Pinocchio's ``GeometryModel``
    ``geometry`` and its shapes' placements and sizes."""
    count = int(geometry.ngeoms)
    rotation, translation = np.zeros((count, 3, 3)), np.zeros((count, 3))
    size = np.zeros((count, 4))
    names = []
    for g, go in enumerate(geometry.geometryObjects):
        name, values = _shape_kind(go.geometry)
        names.append(name)
        size[g, : len(values)] = values
        rotation[g], translation[g] = go.placement.rotation, go.placement.translation
    kind = np.zeros(len(first), dtype=np.int64)
    swapped = np.zeros(len(first), dtype=np.bool_)
    for p, (a, b) in enumerate(zip(first.tolist(), second.tolist(), strict=True)):
        if (names[a], names[b]) in _KINDS:
            kind[p] = _KINDS[names[a], names[b]]
        elif (names[b], names[a]) in _KINDS:
            kind[p], swapped[p] = _KINDS[names[b], names[a]], True
    return ClosedForms(kind, swapped, rotation, translation, size)


@compiled
def _place(
    rot: np.ndarray,
    trans: np.ndarray,
    local_rot: np.ndarray,
    local_trans: np.ndarray,
    out_rot: np.ndarray,
    out_trans: np.ndarray,
) -> None:
    """A shape's world pose ``out_rot``, ``out_trans`` from its joint's ``rot``, ``trans``
    and its pose in the joint's frame ``local_rot``, ``local_trans``."""
    for r in range(3):
        acc = trans[r]
        for m in range(3):
            acc += rot[r, m] * local_trans[m]
        out_trans[r] = acc
        for c in range(3):
            out_rot[r, c] = (
                rot[r, 0] * local_rot[0, c]
                + rot[r, 1] * local_rot[1, c]
                + (rot[r, 2] * local_rot[2, c])
            )


@compiled
def _sphere_sphere(c1: np.ndarray, r1: float, c2: np.ndarray, r2: float, res: np.ndarray) -> float:
    """Two balls: ``res`` rows ``p_1``, ``p_2``, ``n``; the signed distance [m]."""
    dx, dy, dz = c2[0] - c1[0], c2[1] - c1[1], c2[2] - c1[2]
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    ux, uy, uz = 1.0, 0.0, 0.0
    if norm > _CENTRES_M:
        ux, uy, uz = dx / norm, dy / norm, dz / norm
    res[2, 0], res[2, 1], res[2, 2] = ux, uy, uz
    for r in range(3):
        res[0, r] = c1[r] + r1 * res[2, r]
        res[1, r] = c2[r] - r2 * res[2, r]
    return norm - r1 - r2


@compiled
def _sphere_cylinder(
    s: np.ndarray,
    r1: float,
    rot: np.ndarray,
    centre: np.ndarray,
    r2: float,
    half: float,
    res: np.ndarray,
) -> float:
    """A ball of centre ``s`` and radius ``r1``, a cylinder of axis ``rot[:, 2]`` through
    ``centre``, radius ``r2`` and half-length ``half``: ``res`` rows ``p_1``, ``p_2``,
    ``n`` (and a scratch row); the signed distance [m]."""
    along = 0.0
    for r in range(3):
        along += rot[r, 2] * (s[r] - centre[r])
    radial_v = res[3]  # the unit radial direction of the centre (zero on the axis)
    for r in range(3):
        radial_v[r] = s[r] - centre[r] - along * rot[r, 2]
    radial = math.sqrt(radial_v[0] ** 2 + radial_v[1] ** 2 + radial_v[2] ** 2)
    for r in range(3):
        radial_v[r] = radial_v[r] / radial if radial > _AXIS_M else 0.0
    if -half < along <= half:  # beside the side: out radially
        for r in range(3):
            res[2, r] = -radial_v[r]
            res[0, r] = s[r] - r1 * radial_v[r]
            res[1, r] = centre[r] + along * rot[r, 2] + r2 * radial_v[r]
        return radial - r1 - r2
    out = 1.0 if along > half else -1.0  # the cap's outward side along the axis
    if radial <= r2:  # over the cap's disc
        for r in range(3):
            res[2, r] = -out * rot[r, 2]
            res[0, r] = s[r] + r1 * res[2, r]
            res[1, r] = centre[r] + out * half * rot[r, 2] + radial * radial_v[r]
        return out * along - half - r1
    for r in range(3):  # nearest to the rim
        res[1, r] = centre[r] + out * half * rot[r, 2] + r2 * radial_v[r]
    dist = math.sqrt((res[1, 0] - s[0]) ** 2 + (res[1, 1] - s[1]) ** 2 + (res[1, 2] - s[2]) ** 2)
    if dist > _AXIS_M:
        for r in range(3):
            res[2, r] = (res[1, r] - s[r]) / dist
    else:  # the centre on the rim: away from the cylinder's centre
        norm = math.sqrt(
            (res[1, 0] - centre[0]) ** 2
            + (res[1, 1] - centre[1]) ** 2
            + (res[1, 2] - centre[2]) ** 2
        )
        for r in range(3):
            res[2, r] = (res[1, r] - centre[r]) / norm
        dist = 0.0
    for r in range(3):
        res[0, r] = s[r] + r1 * res[2, r]
    return dist - r1


@compiled
def _sphere_box(
    s: np.ndarray, r1: float, rot: np.ndarray, centre: np.ndarray, half: np.ndarray, res: np.ndarray
) -> float:
    """A ball of centre ``s`` and radius ``r1``, a box of axes ``rot``, ``centre`` and half
    sides ``half``: ``res`` rows ``p_1``, ``p_2``, ``n``; the signed distance [m]."""
    outside, face, depth = False, -1, math.inf
    for r in range(3):
        res[1, r] = centre[r]
    for i in range(3):
        x = 0.0  # the centre's coordinate along the box's axis i
        for r in range(3):
            x += rot[r, i] * (s[r] - centre[r])
        if x < -half[i] or x > half[i]:
            x = half[i] if x > 0.0 else -half[i]
            outside = True
        elif half[i] - abs(x) < depth:
            face, depth = i, half[i] - abs(x)
            res[3, 0] = 1.0 if x >= 0.0 else -1.0
        for r in range(3):
            res[1, r] += x * rot[r, i]
    if outside:  # the box's point nearest to the centre
        dist = math.sqrt(
            (res[1, 0] - s[0]) ** 2 + (res[1, 1] - s[1]) ** 2 + (res[1, 2] - s[2]) ** 2
        )
        for r in range(3):
            res[2, r] = (res[1, r] - s[r]) / dist
        dist -= r1
    else:  # out through the nearest face
        for r in range(3):
            res[2, r] = -res[3, 0] * rot[r, face]
        dist = -depth - r1
    for r in range(3):
        res[0, r] = s[r] + r1 * res[2, r]
        if not outside or dist <= 0.0:
            res[1, r] = res[0, r] + dist * res[2, r]
    return dist


@compiled
def _support_halfspace(
    point: np.ndarray, normal: np.ndarray, offset: float, res: np.ndarray
) -> float:
    """A shape whose deepest point along the half-space's outward ``normal`` is ``point``
    (``{x : normalᵀx ≤ offset}`` in the world): ``res`` rows ``p_1``, ``p_2``, ``n``; the
    signed distance [m]. ``point`` and ``normal`` may be rows ``1`` and ``3`` of ``res``:
    each element is read before it is written."""
    dist = normal[0] * point[0] + normal[1] * point[1] + normal[2] * point[2] - offset
    for r in range(3):
        res[0, r] = point[r]
        res[1, r] = point[r] - dist * normal[r]
        res[2, r] = -normal[r]
    return dist


@compiled
def _world_halfspace(
    rot: np.ndarray, trans: np.ndarray, size: np.ndarray, out: np.ndarray
) -> float:
    """A half-space's outward normal in the world ``out`` and its offset [m], from its
    normal and offset ``size`` in its frame ``rot``, ``trans``."""
    offset = size[3]
    for r in range(3):
        out[r] = rot[r, 0] * size[0] + rot[r, 1] * size[1] + rot[r, 2] * size[2]
        offset += out[r] * trans[r]
    return offset


@compiled
def _cylinder_support(
    rot: np.ndarray, centre: np.ndarray, r: float, half: float, normal: np.ndarray, out: np.ndarray
) -> None:
    """The point ``out`` of a cylinder (axis ``rot[:, 2]``, ``centre``, radius ``r``,
    half-length ``half``) furthest along ``-normal``: on the rim, or the disc's centre
    where ``normal`` is along the axis, or the side's middle where it is across it."""
    dx, dy, dz = 0.0, 0.0, 0.0  # -normal in the cylinder's frame
    for m in range(3):
        dx -= rot[m, 0] * normal[m]
        dy -= rot[m, 1] * normal[m]
        dz -= rot[m, 2] * normal[m]
    z = 0.0
    if dz > _ALIGNED:
        z = half
    elif dz < -_ALIGNED:
        z = -half
    across = math.sqrt(dx * dx + dy * dy)
    x, y = 0.0, 0.0
    if abs(dx) > _ALIGNED or abs(dy) > _ALIGNED:
        x, y = r * dx / across, r * dy / across
    for m in range(3):
        out[m] = centre[m] + rot[m, 0] * x + rot[m, 1] * y + rot[m, 2] * z


@compiled
def _pair_distance(
    kind: int,
    rot1: np.ndarray,
    trans1: np.ndarray,
    size1: np.ndarray,
    rot2: np.ndarray,
    trans2: np.ndarray,
    size2: np.ndarray,
    res: np.ndarray,
) -> float:
    """The closed form ``kind`` of two placed shapes (the kind's first shape first):
    ``res`` rows ``p_1``, ``p_2``, ``n``; the signed distance [m]."""
    if kind == SPHERE_SPHERE:
        return _sphere_sphere(trans1, size1[0], trans2, size2[0], res)
    if kind == SPHERE_CYLINDER:
        return _sphere_cylinder(trans1, size1[0], rot2, trans2, size2[0], size2[1], res)
    if kind == SPHERE_BOX:
        return _sphere_box(trans1, size1[0], rot2, trans2, size2[:3], res)
    offset = _world_halfspace(rot2, trans2, size2, res[3])
    if kind == SPHERE_HALFSPACE:
        for r in range(3):
            res[1, r] = trans1[r] - size1[0] * res[3, r]
    else:
        _cylinder_support(rot1, trans1, size1[0], size1[1], res[3], res[1])
    return _support_halfspace(res[1], res[3], offset, res)  # read before written, row by row


@compiled
def solve_closed_forms(
    rot: np.ndarray,
    trans: np.ndarray,
    states: np.ndarray,
    pairs: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
    joint_of: np.ndarray,
    kind: np.ndarray,
    swapped: np.ndarray,
    local_rot: np.ndarray,
    local_trans: np.ndarray,
    size: np.ndarray,
    solved: np.ndarray,
    points: np.ndarray,
) -> np.ndarray:
    """Solve the closed-form pairs among ``(states[m], pairs[m])`` from the joint
    placements ``rot`` ``(N, njoints, 3, 3)``, ``trans`` ``(N, njoints, 3)``: their
    distance ``solved[m]`` [m] and witness points ``a``, ``b`` and normal ``points[m]``
    ``(3, 3)``. Returns which were solved ``(K,)`` (the others are left for coal)."""
    done = np.zeros(states.shape[0], dtype=np.bool_)
    rot1, rot2 = np.empty((3, 3)), np.empty((3, 3))
    trans1, trans2 = np.empty(3), np.empty(3)
    res = np.empty((4, 3))
    for m in range(states.shape[0]):
        p, i = pairs[m], states[m]
        if kind[p] == COAL:
            continue
        g1, g2 = (second[p], first[p]) if swapped[p] else (first[p], second[p])
        j1, j2 = joint_of[g1], joint_of[g2]
        _place(rot[i, j1], trans[i, j1], local_rot[g1], local_trans[g1], rot1, trans1)
        _place(rot[i, j2], trans[i, j2], local_rot[g2], local_trans[g2], rot2, trans2)
        solved[m] = _pair_distance(kind[p], rot1, trans1, size[g1], rot2, trans2, size[g2], res)
        sign = -1.0 if swapped[p] else 1.0
        for r in range(3):
            points[m, 0, r] = res[1, r] if swapped[p] else res[0, r]
            points[m, 1, r] = res[0, r] if swapped[p] else res[1, r]
            points[m, 2, r] = sign * res[2, r]
        done[m] = True
    return done
