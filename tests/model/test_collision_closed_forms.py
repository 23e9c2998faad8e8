"""The closed-form distances against coal's for the same placed shapes, and the collision
model's queries with them against those with coal alone."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest

from dqcontrol import load_lbr4p, load_panda
from dqcontrol.cli.bench_cmd import load_bench
from dqcontrol.controllers.limits.collision import CollisionLimit
from dqcontrol.model import LBR4P_Q0, PANDA_Q0
from dqcontrol.model.collision import Box, CollisionModel, HalfSpace, Sphere
from dqcontrol.model.collision_closed_forms import (
    COAL,
    closed_form_table,
    solve_closed_forms,
)

#: Largest difference to coal [m] (distance, points) or unitless (normal) over the draws.
TOLERANCE = 1e-9


def _rotation(rng: np.random.Generator) -> np.ndarray:
    quat = rng.normal(size=4)
    w, x, y, z = quat / np.linalg.norm(quat)
    return pin.Quaternion(w, x, y, z).matrix()


def _pair(shape_a: coal.ShapeBase, shape_b: coal.ShapeBase) -> tuple:
    """Two shapes on the world joint, their one pair, and coal's request as the model's."""
    geometry = pin.GeometryModel()
    for name, shape in (("a", shape_a), ("b", shape_b)):
        geometry.addGeometryObject(pin.GeometryObject(name, 0, 0, pin.SE3.Identity(), shape))
    geometry.addCollisionPair(pin.CollisionPair(0, 1))
    data = pin.GeometryData(geometry)
    data.distanceRequests[0].gjk_tolerance = 1e-9
    data.distanceRequests[0].epa_tolerance = 1e-9
    return geometry, data


def _both(geometry, data, place_a: pin.SE3, place_b: pin.SE3) -> tuple:
    """Coal's and the closed form's distance, witness points and normal ``(3, 3)``."""
    data.oMg[0], data.oMg[1] = place_a, place_b
    res = pin.computeDistance(geometry, data, 0)
    want = np.array([res.getNearestPoint1(), res.getNearestPoint2(), res.normal])
    for go, place in zip(geometry.geometryObjects, (place_a, place_b), strict=True):
        go.placement = place
    first, second = np.array([0]), np.array([1])
    table = closed_form_table(geometry, first, second)
    assert table.kind[0] != COAL
    eye = np.eye(3)[None, None]
    solved, points, todo = solve_closed_forms(
        eye, np.zeros((1, 1, 3)), np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64),
        first, second, np.zeros(2, dtype=np.int64), *table,
    )  # fmt: skip
    assert todo.size == 0
    return res.min_distance, want, solved[0], points[0]


def _compare(shape_a, shape_b, draws, tolerance=TOLERANCE) -> dict:
    """Worst differences to coal over ``draws`` ``(place_a, place_b)``; both signs seen."""
    geometry, data = _pair(shape_a, shape_b)
    worst = {"distance": 0.0, "points": 0.0, "normal": 0.0}
    signs = set()
    for place_a, place_b in draws:
        d_coal, want, d, got = _both(geometry, data, place_a, place_b)
        signs.add(d_coal > 0.0)
        worst["distance"] = max(worst["distance"], abs(d - d_coal))
        worst["points"] = max(worst["points"], np.abs(got[:2] - want[:2]).max())
        worst["normal"] = max(worst["normal"], np.abs(got[2] - want[2]).max())
    assert signs == {True, False}, "draws both separated and penetrating"
    assert max(worst.values()) < tolerance, worst
    return worst


def _around(rng, count, centre_spread, fixed=None) -> list:
    """``count`` placements: ``b`` at a random pose, ``a`` within ``centre_spread`` [m] of
    it (per axis of ``b``'s frame), both turned at random."""
    out = []
    for _ in range(count):
        place_b = fixed if fixed is not None else pin.SE3(_rotation(rng), rng.uniform(-1, 1, 3))
        local = rng.uniform(-1.0, 1.0, 3) * centre_spread
        place_a = pin.SE3(_rotation(rng), place_b.act(local))
        out.append((place_a, place_b))
    return out


@pytest.mark.parametrize("order", ["ab", "ba"])
def test_sphere_sphere_is_coal(order):
    rng = np.random.default_rng(1)
    shapes = (coal.Sphere(0.07), coal.Sphere(0.12))
    draws = _around(rng, 400, np.array([0.3, 0.3, 0.3]))
    if order == "ba":
        shapes, draws = shapes[::-1], [(b, a) for a, b in draws]
    _compare(*shapes, draws)


@pytest.mark.parametrize("order", ["ab", "ba"])
def test_sphere_cylinder_is_coal(order):
    """Centres beside the side, over the caps and near the rims, outside and inside."""
    rng = np.random.default_rng(2)
    shapes = (coal.Sphere(0.06), coal.Cylinder(0.1, 0.4))
    draws = _around(rng, 800, np.array([0.25, 0.25, 0.35]))
    if order == "ba":
        shapes, draws = shapes[::-1], [(b, a) for a, b in draws]
    _compare(*shapes, draws)


def test_a_sphere_centre_on_the_cylinder_axis_has_coal_zero_normal():
    geometry, data = _pair(coal.Sphere(0.05), coal.Cylinder(0.1, 0.4))
    rotation = _rotation(np.random.default_rng(3))
    place_b = pin.SE3(rotation, np.array([0.2, -0.1, 0.5]))
    place_a = pin.SE3(np.eye(3), place_b.act(np.array([0.0, 0.0, 0.05])))
    d_coal, want, d, got = _both(geometry, data, place_a, place_b)
    assert abs(d - d_coal) < TOLERANCE and np.abs(got - want).max() < TOLERANCE
    assert not np.any(got[2])


@pytest.mark.parametrize("order", ["ab", "ba"])
def test_sphere_box_is_coal(order):
    rng = np.random.default_rng(4)
    shapes = (coal.Sphere(0.05), coal.Box(0.1, 0.2, 0.3))
    draws = _around(rng, 600, np.array([0.15, 0.2, 0.25]))
    if order == "ba":
        shapes, draws = shapes[::-1], [(b, a) for a, b in draws]
    _compare(*shapes, draws)


def _over_plane(rng, count, height) -> list:
    return [
        (pin.SE3(_rotation(rng), rng.uniform(-1, 1, 3) + [0, 0, height]), pin.SE3.Identity())
        for _ in range(count)
    ]


@pytest.mark.parametrize("order", ["ab", "ba"])
def test_sphere_and_cylinder_against_a_half_space_are_coal(order):
    """Tilted shapes at random, and a cylinder upright and lying (coal's ties)."""
    rng = np.random.default_rng(5)
    plane = coal.Halfspace(np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9]), 0.1)
    upright = pin.SE3(np.eye(3), np.array([0.1, 0.2, 0.15]))
    lying = pin.SE3(pin.utils.rotate("x", np.pi / 2), np.array([0.1, 0.2, 0.05]))
    flat = coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.1)
    for shapes, draws in (
        ((coal.Sphere(0.08), plane), _over_plane(rng, 300, 0.1)),
        ((coal.Cylinder(0.05, 0.3), plane), _over_plane(rng, 300, 0.1)),
        (
            (coal.Cylinder(0.05, 0.3), flat),
            [(upright, pin.SE3.Identity()), (lying, pin.SE3.Identity())],
        ),
    ):
        if order == "ba":
            shapes, draws = shapes[::-1], [(b, a) for a, b in draws]
        geometry, data = _pair(*shapes)
        for place_a, place_b in draws:
            d_coal, want, d, got = _both(geometry, data, place_a, place_b)
            assert abs(d - d_coal) < TOLERANCE
            assert np.abs(got - want).max() < TOLERANCE


def test_other_pairs_stay_on_coal():
    shapes = [coal.Sphere(0.1), coal.Cylinder(0.1, 0.2), coal.Capsule(0.1, 0.2), coal.Box(1, 1, 1)]
    geometry = pin.GeometryModel()
    for k, shape in enumerate(shapes):
        geometry.addGeometryObject(pin.GeometryObject(f"g{k}", 0, 0, pin.SE3.Identity(), shape))
    first, second = np.array([1, 2, 3, 0]), np.array([1, 0, 1, 3])
    table = closed_form_table(geometry, first, second)
    assert table.kind[:3].tolist() == [COAL, COAL, COAL]
    assert table.kind[3] != COAL and not table.swapped[3]


def _bench_cell(robot):
    return load_bench().cell_obstacles(robot)


def _walk(robot, q0, seed, steps=40, spread=0.05):
    rng = np.random.default_rng(seed)
    q = q0.copy()
    for _ in range(steps):
        q = q + rng.uniform(-0.03, 0.03, q.size)
        yield q, q + rng.uniform(-spread, spread, (10, q.size))


def _same_batches(got, want) -> float:
    assert got.state.tolist() == want.state.tolist()
    assert got.pair.tolist() == want.pair.tolist()
    both = np.isfinite(want.distance_m)
    assert np.array_equal(both, np.isfinite(got.distance_m))
    gap = np.abs(got.distance_m[both] - want.distance_m[both]).max(initial=0.0)
    assert gap < TOLERANCE
    assert np.abs(got.gradient - want.gradient).max(initial=0.0) < 1e-8
    return gap


def test_the_bench_cell_queries_are_coal_only_queries():
    """The LBR4p in the benchmark's cell: the same pairs, distances and gradients with the
    closed forms as with coal alone, and most pairs solved in closed form."""
    robot = load_lbr4p()
    obstacles = _bench_cell(robot)
    fast = CollisionModel(robot, obstacles)
    slow = CollisionModel(robot, obstacles, closed_forms=False)
    for q, qs in _walk(robot, LBR4P_Q0, 7):
        _same_batches(fast.query_batch(qs, 0.1), slow.query_batch(qs, 0.1))
        got, want = fast.query(q, 0.1), slow.query(q, 0.1)
        assert [p.pair for p in got] == [p.pair for p in want]
        for a, b in zip(got, want, strict=True):
            assert abs(a.distance_m - b.distance_m) < TOLERANCE
            for x, y in ((a.point_a_m, b.point_a_m), (a.point_b_m, b.point_b_m)):
                assert np.abs(x - y).max() < TOLERANCE
            assert np.abs(a.normal - b.normal).max() < TOLERANCE
    assert slow.closed_form_count == 0
    assert fast.closed_form_count > 2 * fast.query_count
    assert fast.query_count + fast.closed_form_count == slow.query_count


def test_the_bench_run_is_the_coal_only_run():
    """The benchmark's path-following run (p = 10) in its cell: every batch of predicted
    states queried gives the same pairs, distances and gradients with coal alone."""
    bench = load_bench()
    robot = load_lbr4p()
    obstacles = _bench_cell(robot)
    fast = CollisionModel(robot, obstacles)
    slow = CollisionModel(robot, obstacles, closed_forms=False)
    query, gaps = fast.query_batch, []

    def both(qs, influence_m):
        got = query(qs, influence_m)
        gaps.append(_same_batches(got, slow.query_batch(qs, influence_m)))
        return got

    fast.query_batch = both
    shared = {
        "velocity_limits": bench.THESIS_VEL,
        "acceleration_limit": bench.THESIS_ACCELERATION_LIMIT,
    }
    ctrl = bench.build_controller(
        "pf10", robot, bench.Circle(2.0), bench.PERIOD_S, shared=shared,
        extra_limits=(CollisionLimit(fast),),
    )  # fmt: skip
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    for _ in range(150):
        q = q + bench.PERIOD_S * ctrl.step(q).qd_command
    assert len(gaps) >= 150 and fast.closed_form_count > 10 * fast.query_count


def test_a_mesh_robot_stays_on_coal():
    robot = load_panda()
    obstacles = (
        Sphere(name="ball", position_m=(0.4, 0.1, 0.5), radius_m=0.1),
        Box(name="crate", position_m=(0.5, -0.3, 0.3), size_m=(0.1, 0.2, 0.2)),
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.0),
    )
    fast = CollisionModel(robot, obstacles)
    slow = CollisionModel(robot, obstacles, closed_forms=False)
    for _, qs in _walk(robot, PANDA_Q0, 8, steps=10):
        _same_batches(fast.query_batch(qs, 0.15), slow.query_batch(qs, 0.15))
