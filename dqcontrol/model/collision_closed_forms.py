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
  of the side where it is that close to the plane) and its projection on the plane. In
  those two cases coal's support point is further out by a relative ``1e-10`` (its
  cylinder is inflated there, for GJK), so its distance is lower by at most ``1e-10``
  times the half-length or the radius; here it is the exact one.

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

#: A point or a direction in the world ``(x, y, z)``.
Vec = tuple[float, float, float]
#: A pair's signed distance [m], witness points ``p_1``, ``p_2`` [m] and normal ``n``.
Solution = tuple[float, Vec, Vec, Vec]


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
    rots: np.ndarray,
    transs: np.ndarray,
    slot: int,
) -> None:
    """A shape's world pose ``rots[slot]``, ``transs[slot]`` from its joint's ``rot``,
    ``trans`` and its pose in the joint's frame ``local_rot``, ``local_trans``."""
    lx, ly, lz = local_trans[0], local_trans[1], local_trans[2]
    for r in range(3):
        a0, a1, a2 = rot[r, 0], rot[r, 1], rot[r, 2]
        transs[slot, r] = trans[r] + a0 * lx + a1 * ly + a2 * lz
        for c in range(3):
            rots[slot, r, c] = a0 * local_rot[0, c] + a1 * local_rot[1, c] + a2 * local_rot[2, c]


@compiled
def _sphere_sphere(transs: np.ndarray, r1: float, r2: float) -> Solution:
    """Balls of centres ``transs[0]``, ``transs[1]`` and radii ``r1``, ``r2``."""
    ax, ay, az = transs[0, 0], transs[0, 1], transs[0, 2]
    bx, by, bz = transs[1, 0], transs[1, 1], transs[1, 2]
    dx, dy, dz = bx - ax, by - ay, bz - az
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    ux, uy, uz = 1.0, 0.0, 0.0
    if norm > _CENTRES_M:
        ux, uy, uz = dx / norm, dy / norm, dz / norm
    p1 = (ax + r1 * ux, ay + r1 * uy, az + r1 * uz)
    return norm - r1 - r2, p1, (bx - r2 * ux, by - r2 * uy, bz - r2 * uz), (ux, uy, uz)


@compiled
def _sphere_cylinder(
    rots: np.ndarray, transs: np.ndarray, r1: float, r2: float, half: float
) -> Solution:
    """A ball of centre ``transs[0]`` and radius ``r1``, a cylinder of axis ``rots[1][:,
    2]`` through ``transs[1]``, radius ``r2`` and half-length ``half``."""
    sx, sy, sz = transs[0, 0], transs[0, 1], transs[0, 2]
    cx, cy, cz = transs[1, 0], transs[1, 1], transs[1, 2]
    ux, uy, uz = rots[1, 0, 2], rots[1, 1, 2], rots[1, 2, 2]
    along = ux * (sx - cx) + uy * (sy - cy) + uz * (sz - cz)
    vx, vy, vz = sx - cx - along * ux, sy - cy - along * uy, sz - cz - along * uz
    radial = math.sqrt(vx * vx + vy * vy + vz * vz)
    if radial > _AXIS_M:  # the centre's unit radial direction (zero on the axis)
        vx, vy, vz = vx / radial, vy / radial, vz / radial
    else:
        vx, vy, vz = 0.0, 0.0, 0.0
    if -half < along <= half:  # beside the side: out radially
        p1 = (sx - r1 * vx, sy - r1 * vy, sz - r1 * vz)
        ex, ey, ez = cx + along * ux, cy + along * uy, cz + along * uz
        p2 = (ex + r2 * vx, ey + r2 * vy, ez + r2 * vz)
        return radial - r1 - r2, p1, p2, (-vx, -vy, -vz)
    out = 1.0 if along > half else -1.0  # the cap's outward side along the axis
    ex, ey, ez = cx + out * half * ux, cy + out * half * uy, cz + out * half * uz
    if radial <= r2:  # over the cap's disc
        nx, ny, nz = -out * ux, -out * uy, -out * uz
        p1 = (sx + r1 * nx, sy + r1 * ny, sz + r1 * nz)
        p2 = (ex + radial * vx, ey + radial * vy, ez + radial * vz)
        return out * along - half - r1, p1, p2, (nx, ny, nz)
    qx, qy, qz = ex + r2 * vx, ey + r2 * vy, ez + r2 * vz  # nearest to the rim
    nx, ny, nz = qx - sx, qy - sy, qz - sz
    dist = math.sqrt(nx * nx + ny * ny + nz * nz)
    if not dist > _AXIS_M:  # the centre on the rim: away from the cylinder's centre
        nx, ny, nz, dist = qx - cx, qy - cy, qz - cz, 0.0
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx / norm, ny / norm, nz / norm
    return dist - r1, (sx + r1 * nx, sy + r1 * ny, sz + r1 * nz), (qx, qy, qz), (nx, ny, nz)


@compiled
def _sphere_box(rots: np.ndarray, transs: np.ndarray, r1: float, half: np.ndarray) -> Solution:
    """A ball of centre ``transs[0]`` and radius ``r1``, the box of half sides ``half`` at
    ``rots[1]``, ``transs[1]``."""
    sx, sy, sz = transs[0, 0], transs[0, 1], transs[0, 2]
    bx, by, bz = transs[1, 0], transs[1, 1], transs[1, 2]  # to the box's nearest point
    outside, face, depth, side = False, 0, math.inf, 1.0
    for k in range(3):
        kx, ky, kz = rots[1, 0, k], rots[1, 1, k], rots[1, 2, k]
        x = kx * (sx - transs[1, 0]) + ky * (sy - transs[1, 1]) + kz * (sz - transs[1, 2])
        if x < -half[k] or x > half[k]:
            x = half[k] if x > 0.0 else -half[k]
            outside = True
        elif half[k] - abs(x) < depth:
            face, depth, side = k, half[k] - abs(x), 1.0 if x >= 0.0 else -1.0
        bx, by, bz = bx + x * kx, by + x * ky, bz + x * kz
    if outside:  # towards the box's point nearest to the centre
        nx, ny, nz = bx - sx, by - sy, bz - sz
        dist = math.sqrt(nx * nx + ny * ny + nz * nz)
        nx, ny, nz = nx / dist, ny / dist, nz / dist
        dist -= r1
    else:  # out through the nearest face
        nx, ny, nz = -side * rots[1, 0, face], -side * rots[1, 1, face], -side * rots[1, 2, face]
        dist = -depth - r1
    ax, ay, az = sx + r1 * nx, sy + r1 * ny, sz + r1 * nz
    if not outside or dist <= 0.0:
        bx, by, bz = ax + dist * nx, ay + dist * ny, az + dist * nz
    return dist, (ax, ay, az), (bx, by, bz), (nx, ny, nz)


@compiled
def _cylinder_support(
    rots: np.ndarray, transs: np.ndarray, r: float, half: float, nx: float, ny: float, nz: float
) -> tuple[float, float, float]:
    """The point of the cylinder at ``rots[0]``, ``transs[0]`` (radius ``r``, half-length
    ``half``) furthest along ``-n``: on the rim, or the disc's centre where ``n`` is along
    the axis, or the side's middle where it is across it."""
    dx = -(rots[0, 0, 0] * nx + rots[0, 1, 0] * ny + rots[0, 2, 0] * nz)  # -n, shape's frame
    dy = -(rots[0, 0, 1] * nx + rots[0, 1, 1] * ny + rots[0, 2, 1] * nz)
    dz = -(rots[0, 0, 2] * nx + rots[0, 1, 2] * ny + rots[0, 2, 2] * nz)
    z = 0.0
    if dz > _ALIGNED:
        z = half
    elif dz < -_ALIGNED:
        z = -half
    x, y = 0.0, 0.0
    if abs(dx) > _ALIGNED or abs(dy) > _ALIGNED:
        across = math.sqrt(dx * dx + dy * dy)
        x, y = r * dx / across, r * dy / across
    px = transs[0, 0] + rots[0, 0, 0] * x + rots[0, 0, 1] * y + rots[0, 0, 2] * z
    py = transs[0, 1] + rots[0, 1, 0] * x + rots[0, 1, 1] * y + rots[0, 1, 2] * z
    pz = transs[0, 2] + rots[0, 2, 0] * x + rots[0, 2, 1] * y + rots[0, 2, 2] * z
    return px, py, pz


@compiled
def _halfspace(
    kind: int, rots: np.ndarray, transs: np.ndarray, size1: np.ndarray, plane: np.ndarray
) -> Solution:
    """A sphere or a cylinder (sizes ``size1``) against the half-space ``{x : nᵀx ≤ c}``
    (``plane``: ``n``, ``c`` in its frame): the shape's point deepest along the outward
    normal and its projection on the plane."""
    nx = rots[1, 0, 0] * plane[0] + rots[1, 0, 1] * plane[1] + rots[1, 0, 2] * plane[2]
    ny = rots[1, 1, 0] * plane[0] + rots[1, 1, 1] * plane[1] + rots[1, 1, 2] * plane[2]
    nz = rots[1, 2, 0] * plane[0] + rots[1, 2, 1] * plane[1] + rots[1, 2, 2] * plane[2]
    offset = plane[3] + nx * transs[1, 0] + ny * transs[1, 1] + nz * transs[1, 2]
    if kind == SPHERE_HALFSPACE:
        r = size1[0]
        px, py, pz = transs[0, 0] - r * nx, transs[0, 1] - r * ny, transs[0, 2] - r * nz
    else:
        px, py, pz = _cylinder_support(rots, transs, size1[0], size1[1], nx, ny, nz)
    dist = nx * px + ny * py + nz * pz - offset
    p2 = (px - dist * nx, py - dist * ny, pz - dist * nz)
    return dist, (px, py, pz), p2, (-nx, -ny, -nz)


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
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closed-form pairs among ``(states[m], pairs[m])`` solved from the joint
    placements ``rot`` ``(N, njoints, 3, 3)``, ``trans`` ``(N, njoints, 3)``: distances
    ``(K,)`` [m] and witness points ``a``, ``b`` and normal ``(K, 3, 3)``, NaN for the
    others, and the indices ``m`` of those others (left for coal)."""
    count = states.shape[0]
    solved, points = np.full(count, np.nan), np.full((count, 3, 3), np.nan)
    todo = np.empty(count, dtype=np.int64)
    left = 0
    rots, transs = np.empty((2, 3, 3)), np.empty((2, 3))
    for m in range(count):
        p, i = pairs[m], states[m]
        k = kind[p]
        if k == COAL:
            todo[left] = m
            left += 1
            continue
        g1, g2 = (second[p], first[p]) if swapped[p] else (first[p], second[p])
        j1, j2 = joint_of[g1], joint_of[g2]
        _place(rot[i, j1], trans[i, j1], local_rot[g1], local_trans[g1], rots, transs, 0)
        _place(rot[i, j2], trans[i, j2], local_rot[g2], local_trans[g2], rots, transs, 1)
        if k == SPHERE_SPHERE:
            d, p1, p2, n = _sphere_sphere(transs, size[g1, 0], size[g2, 0])
        elif k == SPHERE_CYLINDER:
            d, p1, p2, n = _sphere_cylinder(rots, transs, size[g1, 0], size[g2, 0], size[g2, 1])
        elif k == SPHERE_BOX:
            d, p1, p2, n = _sphere_box(rots, transs, size[g1, 0], size[g2])
        else:
            d, p1, p2, n = _halfspace(k, rots, transs, size[g1], size[g2])
        if swapped[p]:  # the kind's first shape is b
            p1, p2, n = p2, p1, (-n[0], -n[1], -n[2])
        solved[m] = d
        for r in range(3):
            points[m, 0, r], points[m, 1, r], points[m, 2, r] = p1[r], p2[r], n[r]
    return solved, points, todo[:left]
