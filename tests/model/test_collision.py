"""Collision geometry and distances (docs/theory.md §10.1): the robot's shapes from its
URDF, obstacles, the pairs, distances and gradients checked against finite differences and
against sphere/sphere and sphere/capsule distances computed here, and bad input."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from dqcontrol import load_lbr4p, load_panda
from dqcontrol.errors import ConfigurationError, ParameterError
from dqcontrol.model import LBR4P_Q0, PANDA_Q0, panda_urdf_path
from dqcontrol.model.collision import (
    Box,
    Capsule,
    CollisionModel,
    Cylinder,
    HalfSpace,
    Sphere,
    make_obstacle,
    parse_obstacle,
    read_srdf_pairs,
)

#: Finite-difference step [rad] and the accepted gradient error [m/rad]: GJK solves each
#: distance to about 1e-9 m, which a central difference of step 1e-4 turns into 1e-5.
FD_STEP = 1e-4
FD_TOL = 1e-4


@pytest.fixture(scope="module")
def lbr4p():
    return load_lbr4p()


@pytest.fixture(scope="module")
def panda():
    return load_panda()


def panda_srdf():
    return panda_urdf_path()[0].parent.parent / "srdf" / "panda.srdf"


def fd_gradient(cm: CollisionModel, q: np.ndarray, pair: int) -> np.ndarray:
    out = np.zeros(q.size)
    for j in range(q.size):
        step = np.zeros(q.size)
        step[j] = FD_STEP
        plus = {p.pair: p.distance_m for p in cm.query(q + step, math.inf)}
        minus = {p.pair: p.distance_m for p in cm.query(q - step, math.inf)}
        out[j] = (plus[pair] - minus[pair]) / (2 * FD_STEP)
    return out


OBSTACLES = (
    Sphere(name="ball", position_m=(0.55, 0.1, 0.75), radius_m=0.06),
    Box(name="crate", position_m=(0.3, -0.45, 0.5), size_m=(0.2, 0.1, 0.3)),
    Capsule(
        name="pole",
        position_m=(-0.4, 0.3, 0.8),
        quaternion_wxyz=(math.cos(0.3), math.sin(0.3), 0.0, 0.0),
        radius_m=0.04,
        length_m=0.5,
    ),
    Cylinder(name="drum", position_m=(0.0, 0.6, 0.4), radius_m=0.1, length_m=0.3),
    HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.05),
)


def test_lbr4p_geometry_and_pairs(lbr4p):
    cm = CollisionModel(lbr4p, OBSTACLES)
    assert cm.num_robot_geometries == 15  # the URDF's cylinders and spheres
    links = {link for pair in cm.pair_links for link in pair}
    assert {"lbr4p_link_1", "lbr4p_link_7", "ball", "table"} <= links
    for a, b in cm.pair_links:
        assert a != b
        assert {a, b} != {"lbr4p_link_3", "lbr4p_link_4"}  # adjacent
        assert {a, b} != {"lbr4p_pedestal", "lbr4p_link_0"}  # one rigid body
        assert {a, b} != {"lbr4p_pedestal", "lbr4p_link_1"}  # adjacent through joint 1
    # 13 shapes on moving links against each of 5 obstacles, plus the self pairs
    self_pairs = CollisionModel(lbr4p).num_pairs
    assert cm.num_pairs == self_pairs + 13 * 5
    assert CollisionModel(lbr4p, OBSTACLES, self_collision=False).num_pairs == 13 * 5
    assert cm.min_distance(LBR4P_Q0) > 0.05


@pytest.mark.parametrize("seed", range(4))
def test_lbr4p_gradients_match_finite_differences(lbr4p, seed):
    cm = CollisionModel(lbr4p, OBSTACLES)
    q = lbr4p.random_configurations(1, seed, margin_rad=0.1)[0]
    found = cm.distances(q)
    assert len(found) == cm.num_pairs
    errors = [np.abs(fd_gradient(cm, q, p.pair) - p.gradient).max() for p in found]
    assert max(errors) < FD_TOL
    for p in found:
        if p.distance_m > 1e-6:  # normal = the unit vector between the witness points
            u = (p.point_b_m - p.point_a_m) / p.distance_m
            assert np.allclose(u, p.normal, atol=1e-6)
            assert abs(np.linalg.norm(p.point_b_m - p.point_a_m) - p.distance_m) < 1e-9


def test_influence_distance_keeps_only_near_pairs(lbr4p):
    cm = CollisionModel(lbr4p, OBSTACLES)
    every = {p.pair: p.distance_m for p in cm.distances(LBR4P_Q0)}
    near = cm.distances(LBR4P_Q0, influence_m=0.2)
    assert {p.pair for p in near} == {k for k, d in every.items() if d < 0.2}
    assert cm.candidates(0.2).size <= cm.num_pairs


def _sphere_centre_and_jacobian(robot, q, link="lbr4p_link_4"):
    """Centre of the sphere at the origin of ``link`` and its linear Jacobian (Pinocchio's
    frame Jacobian, not the collision module)."""
    fid = robot.frame_id(link)
    j6 = pin.computeFrameJacobian(robot.model, robot.data, q, fid, pin.LOCAL_WORLD_ALIGNED)
    return robot.data.oMf[fid].translation.copy(), j6[:3].copy()


def _closest_on_segment(p, a, b):
    t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return a + t * (b - a)


@pytest.mark.parametrize("seed", range(5))
def test_sphere_sphere_against_an_independent_computation(lbr4p, seed):
    rng = np.random.default_rng(seed)
    q = lbr4p.random_configurations(1, 10 + seed, margin_rad=0.1)[0]
    centre, jv = _sphere_centre_and_jacobian(lbr4p, q)
    ball = Sphere(name="ball", position_m=centre + rng.uniform(-0.3, 0.3, 3), radius_m=0.05)
    cm = CollisionModel(lbr4p, (ball,), self_collision=False)
    k = [i for i, (g, _) in enumerate(cm.pairs) if g == "lbr4p_link_4_0"][0]  # the sphere
    found = {p.pair: p for p in cm.distances(q)}[k]
    offset = np.array(ball.position_m) - centre
    u = offset / np.linalg.norm(offset)
    assert found.distance_m == pytest.approx(np.linalg.norm(offset) - 0.065 - 0.05, abs=1e-9)
    assert np.allclose(found.point_a_m, centre + 0.065 * u, atol=1e-9)
    assert np.allclose(found.point_b_m, np.array(ball.position_m) - 0.05 * u, atol=1e-9)
    assert np.allclose(found.gradient, -u @ jv, atol=1e-9)


@pytest.mark.parametrize("seed", range(5))
def test_sphere_capsule_against_an_independent_computation(lbr4p, seed):
    rng = np.random.default_rng(100 + seed)
    q = lbr4p.random_configurations(1, 20 + seed, margin_rad=0.1)[0]
    centre, jv = _sphere_centre_and_jacobian(lbr4p, q)
    angle = rng.uniform(0, math.pi)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    quat = (math.cos(angle / 2), *(math.sin(angle / 2) * axis))
    pole = Capsule(
        name="pole",
        position_m=centre + rng.uniform(-0.3, 0.3, 3),
        quaternion_wxyz=quat,
        radius_m=0.03,
        length_m=0.4,
    )
    cm = CollisionModel(lbr4p, (pole,), self_collision=False)
    k = [i for i, (g, _) in enumerate(cm.pairs) if g == "lbr4p_link_4_0"][0]
    found = {p.pair: p for p in cm.distances(q)}[k]
    z = pole.placement().rotation[:, 2]
    mid = np.array(pole.position_m)
    nearest = _closest_on_segment(centre, mid - 0.2 * z, mid + 0.2 * z)
    offset = nearest - centre
    u = offset / np.linalg.norm(offset)
    assert found.distance_m == pytest.approx(np.linalg.norm(offset) - 0.065 - 0.03, abs=1e-8)
    assert np.allclose(found.normal, u, atol=1e-6)
    assert np.allclose(found.gradient, -u @ jv, atol=1e-6)


def test_a_plane_is_the_signed_height(lbr4p):
    floor = HalfSpace(name="floor", normal=(0, 0, 2.0), offset_m=0.3)
    cm = CollisionModel(lbr4p, (floor,), self_collision=False)
    k = [i for i, (g, _) in enumerate(cm.pairs) if g == "lbr4p_link_4_0"][0]
    found = {p.pair: p for p in cm.distances(LBR4P_Q0)}[k]
    centre, jv = _sphere_centre_and_jacobian(lbr4p, LBR4P_Q0)
    assert found.distance_m == pytest.approx(centre[2] - 0.3 - 0.065, abs=1e-9)
    assert np.allclose(found.gradient, jv[2], atol=1e-9)


def test_panda_meshes_work(panda):
    ball = Sphere(name="ball", position_m=(0.45, 0.0, 0.35), radius_m=0.05)
    cm = CollisionModel(panda, (ball,), srdf=panda_srdf())
    assert cm.num_robot_geometries == 17
    assert len(cm.allowed_pairs) > 0
    assert cm.num_pairs < CollisionModel(panda, (ball,)).num_pairs
    assert cm.min_distance(PANDA_Q0) > 0.0
    q = PANDA_Q0 + np.random.default_rng(3).uniform(-0.3, 0.3, 7)
    found = cm.distances(q, influence_m=0.3)
    assert found
    errors = [np.abs(fd_gradient(cm, q, p.pair) - p.gradient).max() for p in found]
    assert max(errors) < FD_TOL


def test_allowed_pairs_and_srdf(lbr4p):
    full = CollisionModel(lbr4p)
    pair = ("lbr4p_link_1", "lbr4p_link_5")
    fewer = CollisionModel(lbr4p, allowed_pairs=[pair])
    assert fewer.num_pairs < full.num_pairs
    assert all(set(p) != set(pair) for p in fewer.pair_links)
    srdf = (
        '<robot name="lbr4p"><disable_collisions link1="lbr4p_link_1" link2="lbr4p_link_5" '
        'reason="test"/></robot>'
    )
    assert read_srdf_pairs(srdf) == (pair,)
    assert CollisionModel(lbr4p, srdf=srdf).pairs == fewer.pairs


def test_a_pair_naming_an_unknown_link_lists_the_links(lbr4p):
    with pytest.raises(ParameterError, match="lbr4p_link_9.*links:.*lbr4p_link_1"):
        CollisionModel(lbr4p, allowed_pairs=[("lbr4p_link_1", "lbr4p_link_9")])
    srdf = '<robot><disable_collisions link1="elbow" link2="lbr4p_link_2"/></robot>'
    with pytest.raises(ParameterError, match="elbow"):
        CollisionModel(lbr4p, srdf=srdf)
    with pytest.raises(ParameterError, match="not found"):
        CollisionModel(lbr4p, srdf="/nonexistent/robot.srdf")


@pytest.mark.parametrize(
    ("build", "field"),
    [
        (lambda: Sphere(radius_m=-0.1), "radius_m"),
        (lambda: Sphere(radius_m=0.0), "radius_m"),
        (lambda: Sphere(radius_m=math.nan), "radius_m"),
        (lambda: Sphere(radius_m=0.1, position_m=(0, math.nan, 0)), "position_m"),
        (lambda: Sphere(radius_m=0.1, position_m=(0, 0, math.inf)), "position_m"),
        (lambda: Sphere(radius_m=0.1, position_m=(0, 0)), "position_m"),
        (lambda: Box(size_m=(0.1, -0.2, 0.1)), r"size_m \(y\)"),
        (lambda: Capsule(radius_m=0.1, length_m=-1.0), "length_m"),
        (lambda: Cylinder(radius_m=math.inf, length_m=1.0), "radius_m"),
        (lambda: Sphere(radius_m=0.1, quaternion_wxyz=(1, 1, 0, 0)), "quaternion_wxyz"),
        (lambda: HalfSpace(normal=(0, 0, 0)), "normal"),
        (lambda: HalfSpace(offset_m=math.nan), "offset_m"),
        (lambda: make_obstacle("cone", radius_m=1.0), "unknown obstacle shape 'cone'"),
        (lambda: make_obstacle("sphere", radius=1.0), "sphere"),
        (lambda: parse_obstacle("cone:0,0,0,1"), "unknown obstacle shape 'cone'"),
        (lambda: parse_obstacle("sphere:0,0,1"), "4 numbers"),
        (lambda: parse_obstacle("sphere:0,0,1,x"), "number"),
        (lambda: parse_obstacle("sphere:0,0,1,-0.1"), "radius_m"),
        (lambda: parse_obstacle("box:0,0,nan,1,1,1"), "position_m"),
    ],
)
def test_bad_obstacles_name_the_field(build, field):
    with pytest.raises(ParameterError, match=field):
        build()


def test_parse_obstacle_forms():
    assert parse_obstacle("sphere:0.5,0,0.6,0.05") == Sphere(
        position_m=(0.5, 0, 0.6), radius_m=0.05
    )
    assert parse_obstacle("box:1,2,3,0.1,0.2,0.3").size_m == (0.1, 0.2, 0.3)
    assert parse_obstacle("capsule:0,0,1,0.1,0.5").length_m == 0.5
    assert parse_obstacle("cylinder:0,0,1,0.1,0.5").kind == "cylinder"
    plane = parse_obstacle("plane:0,0,1,0.2")
    assert plane.normal == (0.0, 0.0, 1.0) and plane.offset_m == 0.2


def test_bad_model_input(lbr4p):
    ball = Sphere(name="x", radius_m=0.1)
    with pytest.raises(ParameterError, match="unique"):
        CollisionModel(lbr4p, (ball, ball))
    with pytest.raises(ParameterError, match="obstacle 0"):
        CollisionModel(lbr4p, ("sphere:0,0,0,1",))
    cm = CollisionModel(lbr4p, (ball,))
    with pytest.raises(ConfigurationError):
        cm.distances(np.full(7, np.nan))
    with pytest.raises(ParameterError, match="influence_m"):
        cm.distances(LBR4P_Q0, influence_m=-1.0)


def test_a_batch_is_the_single_queries(lbr4p, panda):
    """:meth:`CollisionModel.query_batch` gives the rows of :meth:`CollisionModel.query` at
    each configuration."""
    for robot, seed in ((lbr4p, 5), (panda, 6)):
        cm = CollisionModel(robot, OBSTACLES[:1] + OBSTACLES[-1:])
        qs = robot.random_configurations(6, seed, margin_rad=0.2)
        batch = cm.query_batch(qs, 0.25)
        rows = [
            (i, p.pair, p.distance_m, p.gradient)
            for i, q in enumerate(qs)
            for p in cm.query(q, 0.25)
        ]
        assert batch.state.tolist() == [r[0] for r in rows]
        assert batch.pair.tolist() == [r[1] for r in rows]
        # GJK starts from the previous query's answer for each pair: on the Panda's convex
        # hulls its answer moves by up to ~3e-6 m with the start, and where two flat faces
        # are nearest it picks another witness point on them
        assert np.allclose(batch.distance_m, [r[2] for r in rows], atol=1e-5)
        # (apart: overlapping hulls, which random Panda configurations have, give EPA's
        # penetration direction, not unique)
        apart = batch.distance_m > 1e-3
        error = np.abs(batch.gradient - np.array([r[3] for r in rows]))[apart]
        assert error.max() < FD_TOL


def test_batched_kinematics_are_pinocchio(lbr4p, panda):
    """The numpy chain of :meth:`CollisionModel.query_batch` gives Pinocchio's joint
    placements and world Jacobians (a re-based LBR4p too)."""
    based = load_lbr4p(
        base=np.array([[0, -1, 0, 0.1], [1, 0, 0, 0.2], [0, 0, 1, 0.3], [0, 0, 0, 1]])
    )
    for robot in (lbr4p, panda, based):
        cm = CollisionModel(robot)
        qs = robot.random_configurations(5, 1)
        rot, trans, jac = cm._kinematics_batch(qs)
        for i, q in enumerate(qs):
            pin.computeJointJacobians(cm.model, cm.data, q)
            assert np.allclose(jac[i], cm.data.J, atol=1e-12)
            for j in range(1, cm.model.njoints):
                assert np.allclose(rot[i, j], cm.data.oMi[j].rotation, atol=1e-12)
                assert np.allclose(trans[i, j], cm.data.oMi[j].translation, atol=1e-12)


@pytest.mark.parametrize("robot_name", ["lbr4p", "panda"])
def test_the_filter_never_drops_a_pair_within_reach(robot_name, lbr4p, panda):
    """The bounding capsules and support functions give lower bounds of every pair's
    distance, so no pair within the influence distance is filtered out."""
    robot = lbr4p if robot_name == "lbr4p" else panda
    cm = CollisionModel(robot, OBSTACLES)
    qs = robot.random_configurations(20, 7, margin_rad=0.1)
    rot, trans, _ = cm._kinematics_batch(qs)
    bounds = cm._gaps(rot, trans, math.inf)
    for i, q in enumerate(qs):
        true = np.full(cm.num_pairs, np.inf)
        for p in cm.query(q, math.inf):
            true[p.pair] = p.distance_m
        finite = np.isfinite(true)
        assert np.all(bounds[i][finite] <= true[finite] + 1e-9)
    assert np.mean(bounds > 0.0) > 0.5  # and they are not trivially low


def _hull_distance_m(a: np.ndarray, b: np.ndarray) -> float:
    """The distance between the convex hulls of the points ``a`` and ``b`` ``(k, 3)``: the
    nearest convex combinations, a QP over the hulls' vertices (quadprog)."""
    import quadprog
    from scipy.spatial import ConvexHull

    a, b = a[ConvexHull(a).vertices], b[ConvexHull(b).vertices]
    m = np.hstack([a.T, -b.T])
    na, nb = len(a), len(b)
    g = m.T @ m + 1e-12 * np.eye(na + nb)
    sums = np.vstack([np.r_[np.ones(na), np.zeros(nb)], np.r_[np.zeros(na), np.ones(nb)]])
    c = np.vstack([sums, np.eye(na + nb)]).T
    x = quadprog.solve_qp(g, np.zeros(na + nb), c, np.r_[1.0, 1.0, np.zeros(na + nb)], meq=2)[0]
    return float(np.linalg.norm(m @ x))


@pytest.mark.parametrize("arm", ["panda", "xarm7"])
def test_mesh_distances_are_those_of_the_convex_hulls(panda, arm):
    import coal

    """Every self pair within 10 cm at three seeded configurations of the Panda and of
    example-robot-data's xArm7 (concave links): the distance is the one between the convex
    hulls of the URDF's collision meshes (read again here, vertices from the mesh files),
    not of a smaller shape."""
    if arm == "xarm7":
        pytest.importorskip("example_robot_data")
        from dqcontrol.cli.robot_options import RobotRequest, load_robot

        robot = load_robot(RobotRequest("erd:xarm7", "link_eef"))[0]
        q_mid = np.array([0.0, 0.0, 0.0, 0.5, 0.0, 0.5, 0.0])  # near the vertical
    else:
        robot, q_mid = panda, PANDA_Q0
    src = robot.source
    raw = pin.buildGeomFromUrdfString(
        pin.buildModelFromXML(src.xml), src.xml_with_mesh_paths(), pin.GeometryType.COLLISION
    )
    vertices = {
        go.name: np.array([go.geometry.vertex(i) for i in range(go.geometry.num_vertices)])
        for go in raw.geometryObjects
        if isinstance(go.geometry, coal.BVHModelBase)
    }
    cm = CollisionModel(robot, (), self_collision=True)
    names = [go.name for go in cm.geometry.geometryObjects]
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(3):
        q = np.clip(q_mid + rng.uniform(-0.6, 0.6, 7), robot.limits.q_min, robot.limits.q_max)
        pin.forwardKinematics(cm.model, cm.data, q)
        pin.updateGeometryPlacements(cm.model, cm.data, cm.geometry, cm.geometry_data)
        for found in cm.distances(q, influence_m=0.1):
            name_a, name_b = cm.pairs[found.pair]
            if name_a not in vertices or name_b not in vertices:
                continue  # a primitive shape
            world = []
            for name in (name_a, name_b):
                placement = cm.geometry_data.oMg[names.index(name)]
                world.append(vertices[name] @ placement.rotation.T + placement.translation)
            expected = _hull_distance_m(*world)
            if expected <= 1e-9:  # the hulls overlap: a penetration depth, not a distance
                assert found.distance_m <= 2e-6, (name_a, name_b)
            else:
                assert found.distance_m == pytest.approx(expected, abs=2e-6), (name_a, name_b)
            checked += 1
    assert checked >= 5
