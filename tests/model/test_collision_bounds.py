"""The broad phase of the collision queries: segment distances against a dense search, the
capsule and support bounds against coal's distances on seeded random poses (never above,
exact for a half-space), the same bounds below an influence distance as without one, and
the bound from a pair's last solved distance (never drops a pair within reach, same answers
as a fresh model)."""

from __future__ import annotations

import math

import coal
import numpy as np
import pinocchio as pin
import pytest

from dqcontrol import load_lbr4p
from dqcontrol.model.collision import Box, CollisionModel, HalfSpace, Sphere
from dqcontrol.model.collision_bounds import bounding_capsule, support_form
from dqcontrol.model.collision_kernels import (
    FORM_SIZE,
    capsule_gaps,
)

SHAPES = (
    coal.Sphere(0.07),
    coal.Cylinder(0.065, 0.2),
    coal.Capsule(0.05, 0.3),
    coal.Box(0.1, 0.2, 0.05),
)


def _random_pose(rng: np.random.Generator) -> pin.SE3:
    return pin.SE3(pin.exp3(rng.normal(size=3)), rng.uniform(-0.25, 0.25, 3))


_SHAPE_DATA: dict[int, tuple] = {}


def _shape_data(shape) -> tuple:
    """The bounding capsule's ends and radius and the support form of ``shape``, computed
    once per shape (the shape is kept with them, so its id stays its own)."""
    entry = _SHAPE_DATA.get(id(shape))
    if entry is None or entry[0] is not shape:
        capsule = bounding_capsule(shape)
        centre, spans, axis, disc, ball = support_form(shape, capsule)
        form = np.concatenate([centre, spans.ravel(), axis, [disc, ball]])
        entry = _SHAPE_DATA[id(shape)] = (shape, (capsule[:2], capsule[2], form))
    return entry[1]


def _gap_of(shape_a, pose_a, shape_b, pose_b, plane=None, influence_m=math.inf) -> float:
    """``capsule_gaps`` for one pair of shapes (each on its own joint, placed by pose)."""
    rot = np.stack([np.eye(3), pose_a.rotation, pose_b.rotation])[None]
    trans = np.stack([np.zeros(3), pose_a.translation, pose_b.translation])[None]
    ends, radii, forms = np.zeros((2, 2, 3)), np.zeros(2), np.zeros((2, FORM_SIZE))
    for k, shape in enumerate((shape_a, shape_b)):
        if shape is not None:
            ends[k], radii[k], forms[k] = _shape_data(shape)
    normals, offsets = np.zeros((2, 3)), np.zeros(2)
    is_plane = np.array([False, plane is not None])
    if plane is not None:
        normals[1], offsets[1] = plane
    one = np.array([0], dtype=np.int64)
    return float(
        capsule_gaps(
            rot, trans, np.array([1, 2]), ends, radii, forms, one, one + 1,
            normals, offsets, is_plane, influence_m,
        )[0, 0]
    )  # fmt: skip


@pytest.mark.parametrize("first", range(len(SHAPES)))
@pytest.mark.parametrize("second", range(len(SHAPES)))
def test_bounds_never_exceed_coal(first, second):
    """On seeded random poses the bound is at most coal's distance (GJK's tolerance aside)
    where the shapes are apart, and not positive where they overlap (coal's penetration
    depths of curved shapes are not compared: an overlapping pair is always solved)."""
    rng = np.random.default_rng(100 * first + second)
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    req.gjk_tolerance = req.epa_tolerance = 1e-10
    a, b = SHAPES[first], SHAPES[second]
    for _ in range(200):
        pa, pb = _random_pose(rng), _random_pose(rng)
        res.clear()
        exact = coal.distance(a, coal.Transform3s(pa), b, coal.Transform3s(pb), req, res)
        assert _gap_of(a, pa, b, pb) <= max(exact, 0.0) + 1e-7


@pytest.mark.parametrize("index", range(len(SHAPES)))
def test_a_half_space_bound_is_coal_distance(index):
    rng = np.random.default_rng(index)
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    shape = SHAPES[index]
    for _ in range(100):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        offset = float(rng.uniform(-0.2, 0.2))
        pose = _random_pose(rng)
        res.clear()
        plane = coal.Halfspace(normal, offset)
        exact = coal.distance(shape, coal.Transform3s(pose), plane, coal.Transform3s(), req, res)
        bound = _gap_of(shape, pose, None, pin.SE3.Identity(), plane=(normal, offset))
        assert bound == pytest.approx(exact, abs=1e-8)


INFLUENCES_M = (0.005, 0.03, 0.1, 0.3)


@pytest.mark.parametrize("first", range(len(SHAPES)))
@pytest.mark.parametrize("second", range(len(SHAPES)))
def test_an_influence_distance_keeps_the_bound_below_it(first, second):
    """Cut off at ``d_i`` (bounding balls first, the support gaps only while the bound is
    below ``d_i``), the bound is the uncut one wherever either is below ``d_i``, never
    above coal's distance, and at least ``d_i`` elsewhere: the same pairs pass."""
    rng = np.random.default_rng(1000 + 10 * first + second)
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    req.gjk_tolerance = req.epa_tolerance = 1e-10
    a, b = SHAPES[first], SHAPES[second]
    passed = 0
    for trial in range(300):
        pa, pb = _random_pose(rng), _random_pose(rng)
        if trial % 2:  # far apart too, where the balls decide
            pb = pin.SE3(pb.rotation, pb.translation + rng.uniform(-0.6, 0.6, 3))
        full = _gap_of(a, pa, b, pb)
        res.clear()
        exact = coal.distance(a, coal.Transform3s(pa), b, coal.Transform3s(pb), req, res)
        for influence in INFLUENCES_M:
            cut = _gap_of(a, pa, b, pb, influence_m=influence)
            assert cut <= max(exact, 0.0) + 1e-7
            if min(cut, full) < influence:
                assert cut == full
                passed += 1
            else:
                assert cut >= influence
    assert passed > 100


@pytest.mark.parametrize("index", range(len(SHAPES)))
def test_a_half_space_bound_is_kept_below_an_influence_distance(index):
    rng = np.random.default_rng(50 + index)
    shape, normal = SHAPES[index], np.array([0.0, 0.0, 1.0])
    passed = 0
    for _ in range(200):
        pose = _random_pose(rng)
        plane = (normal, float(rng.uniform(-0.6, 0.3)))
        full = _gap_of(shape, pose, None, pin.SE3.Identity(), plane=plane)
        for influence in INFLUENCES_M:
            cut = _gap_of(shape, pose, None, pin.SE3.Identity(), plane, influence)
            if min(cut, full) < influence:
                assert cut == full
                passed += 1
            else:
                assert cut >= influence and cut <= full
    assert passed > 50


def test_a_convex_hull_is_inside_its_capsule():
    from dqcontrol import load_panda

    model = CollisionModel(load_panda())
    for go in model.geometry.geometryObjects:
        shape = go.geometry
        if not isinstance(shape, coal.ConvexBase):
            continue
        start, end, radius = bounding_capsule(shape)
        points = np.asarray(shape.points())
        step = end - start
        t = np.clip((points - start) @ step / max(step @ step, 1e-300), 0.0, 1.0)
        assert np.linalg.norm(points - start - t[:, None] * step, axis=1).max() <= radius + 1e-12


def test_last_distances_never_drop_a_pair():
    """With each pair's last solved distance as a bound, a walk of queries finds the same
    pairs and distances as a model without memory."""
    robot = load_lbr4p()
    obstacles = (
        Sphere(name="ball", position_m=(0.3, -0.2, 0.9), radius_m=0.08),
        Box(name="crate", position_m=(0.4, 0.3, 0.5), size_m=(0.1, 0.1, 0.2)),
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.2),
    )
    warm, fresh_model = CollisionModel(robot, obstacles), CollisionModel(robot, obstacles)
    rng = np.random.default_rng(11)
    q = robot.random_configurations(1, 4, margin_rad=0.3)[0]
    for _ in range(60):
        q = q + rng.uniform(-0.02, 0.02, q.size)
        qs = q + rng.uniform(-0.03, 0.03, (5, q.size))
        fresh_model._reference_m[:] = -math.inf  # forget: the capsules alone
        got, want = warm.query_batch(qs, 0.15), fresh_model.query_batch(qs, 0.15)
        assert got.state.tolist() == want.state.tolist()
        assert got.pair.tolist() == want.pair.tolist()
        assert np.allclose(got.distance_m, want.distance_m, atol=1e-7)
    assert warm.query_count < fresh_model.query_count
