"""Bounding capsules of collision shapes: the broad phase of the distance queries.

Every shape lies inside a capsule (the points within a radius of a segment) fixed in the
shape's frame. Two shapes are then at least as far apart as their capsules, and the
capsules' distance is the distance between their segments less the two radii, which a few
dozen flops give (:mod:`dqcontrol.model.collision_kernels`). A capsule is much tighter than a
bounding ball around a long link, so far fewer pairs reach the exact (GJK) query.

- a sphere is a capsule of zero length, a capsule is itself;
- a cylinder of radius ``r`` and half-length ``h`` is inside the capsule of the same radius
  around its axis from ``-h`` to ``h`` (a rim point is ``r`` from the axis' end);
- a box or a convex mesh is inside the capsule that contains all its vertices (a capsule is
  convex, so it then holds their hull): the segment is along one of the vertices' principal
  axes, and its length is chosen to make the capsule smallest;
- any other shape is inside the ball around its bounding box (zero length).

Each shape also has a support function ``h(u) = max_{x ∈ shape} uᵀx`` (:func:`support_form`),
exact for the primitives and the bounding capsule's otherwise: for any unit ``u``, two
convex shapes are at least ``-h_b(-u) - h_a(u)`` apart (the gap between two parallel planes
that separate them, negative where they overlap), which is exact along the right ``u`` and
tighter than the capsules where flat ends face each other. A shape's distance to a
half-space ``{x : nᵀx ≤ c}`` is exactly ``-h(-n) - c``.

A pair's distance found at one configuration also bounds it nearby (:func:`pair_levers`):
the distance between two rigid shapes changes by at most how far their points move relative
to each other.
"""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin

__all__ = ["bounding_capsule", "pair_levers", "support_form", "vertex_capsule"]

#: Segment lengths tried for a vertex capsule, as fractions of the vertices' extent along
#: the axis: the capsule's ends are rounded, so a shorter segment with a larger radius may
#: enclose the vertices more tightly.
_LENGTH_FRACTIONS = np.linspace(0.0, 1.0, 21)


def bounding_capsule(shape: coal.ShapeBase) -> tuple[np.ndarray, np.ndarray, float]:
    """A capsule containing ``shape``, in the shape's frame: its segment's two ends [m]
    ``(3,)`` and its radius [m]."""
    if isinstance(shape, coal.Sphere):
        return np.zeros(3), np.zeros(3), float(shape.radius)
    if isinstance(shape, (coal.Capsule, coal.Cylinder)):
        half = np.array([0.0, 0.0, float(shape.halfLength)])
        return -half, half, float(shape.radius)
    if isinstance(shape, coal.Box):
        half = np.asarray(shape.halfSide, dtype=float)
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return vertex_capsule(corners * half)
    if isinstance(shape, coal.ConvexBase):
        return vertex_capsule(np.asarray(shape.points(), dtype=float))
    shape.computeLocalAABB()
    centre = np.asarray(shape.aabb_center, dtype=float)
    return centre.copy(), centre.copy(), float(shape.aabb_radius)


def support_form(
    shape: coal.ShapeBase, capsule: tuple[np.ndarray, np.ndarray, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """The terms of ``shape``'s support function in its own frame.

    The support function is

        h(u) = uᵀc + Σ_i |uᵀs_i| + ρ √(1 - (uᵀa)²) + r      (|u| = 1),

    with centre ``c`` [m] ``(3,)``, half-spans ``s_i`` [m] ``(3, 3)`` (rows), disc axis ``a``
    ``(3,)``, disc radius ``ρ`` [m] and ball radius ``r`` [m]: a box is its three half
    sides, a cylinder a half-length along its axis and a disc, a capsule a half-length and
    a ball, a sphere a ball; any other shape takes its bounding ``capsule`` (ends, radius),
    which contains it (a larger support, so still a lower bound of distances)."""
    centre, spans, axis = np.zeros(3), np.zeros((3, 3)), np.zeros(3)
    if isinstance(shape, coal.Sphere):
        return centre, spans, axis, 0.0, float(shape.radius)
    if isinstance(shape, coal.Capsule):
        spans[0, 2] = float(shape.halfLength)
        return centre, spans, axis, 0.0, float(shape.radius)
    if isinstance(shape, coal.Cylinder):
        spans[0, 2], axis[2] = float(shape.halfLength), 1.0
        return centre, spans, axis, float(shape.radius), 0.0
    if isinstance(shape, coal.Box):
        return centre, np.diag(np.asarray(shape.halfSide, dtype=float)), axis, 0.0, 0.0
    start, end, radius = capsule
    spans[0] = 0.5 * (end - start)
    return 0.5 * (start + end), spans, axis, 0.0, radius


def vertex_capsule(points_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The smallest (by volume) of a few capsules that contain every point of ``points_m``
    ``(k, 3)`` [m], with segments along the points' principal axes: ends ``(3,)`` and
    radius [m]. The radius is the largest distance of a point from the segment, so every
    point is inside whatever segment is chosen."""
    centre = points_m.mean(axis=0)
    spread = points_m - centre
    _, _, axes = np.linalg.svd(spread, full_matrices=False)
    best: tuple[float, np.ndarray, np.ndarray, float] | None = None
    for axis in axes:
        along = spread @ axis
        low, high = float(along.min()), float(along.max())
        mid, half = 0.5 * (low + high), 0.5 * (high - low)
        for fraction in _LENGTH_FRACTIONS:
            start = centre + (mid - fraction * half) * axis
            end = centre + (mid + fraction * half) * axis
            radius = _farthest_from_segment(points_m, start, end)
            volume = np.pi * radius**2 * (2.0 * fraction * half + 4.0 / 3.0 * radius)
            if best is None or volume < best[0]:
                best = (volume, start, end, radius)
    assert best is not None
    return best[1], best[2], best[3]


def _farthest_from_segment(points_m: np.ndarray, start: np.ndarray, end: np.ndarray) -> float:
    """The largest distance [m] of ``points_m`` ``(k, 3)`` from the segment ``start``–``end``."""
    step = end - start
    length2 = float(step @ step)
    t = np.zeros(len(points_m))
    if length2 > 0.0:
        t = np.clip((points_m - start) @ step / length2, 0.0, 1.0)
    nearest = start + t[:, None] * step
    return float(np.linalg.norm(points_m - nearest, axis=1).max())


def pair_levers(
    model: pin.Model,
    joint_of: np.ndarray,
    ends_m: np.ndarray,
    radii_m: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
) -> np.ndarray:
    """How far [m/rad] a point of either shape of each pair may move, relative to the other
    shape, per radian of each joint ``(pairs, nq)``, for a model of revolute joints.

    Joint ``k`` turns the shapes below it about an axis through its origin ``o_k``; a joint
    above both shapes of a pair turns them together and leaves their distance. A point ``x``
    of shape ``g`` on joint ``j`` is within ``|x - o_j| ≤ max|end| + radius`` of ``o_j`` (its
    bounding capsule, :func:`bounding_capsule`, in joint ``j``'s frame), and each joint up the
    chain adds the length of its placement's translation (triangle inequality), a bound at
    every configuration. ``ends_m`` ``(g, 2, 3)`` and ``radii_m`` ``(g,)``: the capsules in
    their joints' frames; ``first``, ``second``: each pair's shapes."""
    levers = np.zeros((first.size, model.nq))
    for p, (a, b) in enumerate(zip(first.tolist(), second.tolist(), strict=True)):
        above_a, above_b = _chain(model, int(joint_of[a])), _chain(model, int(joint_of[b]))
        for shape, others in ((a, above_b), (b, above_a)):
            reach = float(np.linalg.norm(ends_m[shape], axis=1).max() + radii_m[shape])
            for k in _chain(model, int(joint_of[shape])):
                if k in others:
                    break  # a common ancestor: the pair turns as one
                levers[p, model.idx_qs[k]] = reach
                reach += float(np.linalg.norm(model.jointPlacements[k].translation))
    return levers


def _chain(model: pin.Model, joint: int) -> list[int]:
    """``joint`` and its ancestors up to the universe (excluded)."""
    out = []
    while joint > 0:
        out.append(joint)
        joint = int(model.parents[joint])
    return out
