"""dqcontrol/sim/mjcf_builder.py: obstacles added to the robot's MuJoCo model as static geoms
and contacts counted by MuJoCo's own collision detection (docs/theory.md §10.6), checked
against coal's distances; and the hinge of a continuous joint left unlimited. (The collision
limit's runs replayed in MuJoCo, with it as the oracle, are tested in
tests/controllers/limits/test_collision.py.)"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from model.test_pinocchio_model import _first_joint_continuous

from dqcontrol import load_lbr4p
from dqcontrol.model import LBR4P_Q0, RobotModel, lbr4p_urdf_path
from dqcontrol.model.collision import Box, Capsule, CollisionModel, Cylinder, HalfSpace, Sphere
from dqcontrol.sim import MujocoSimulation
from dqcontrol.sim.mjcf_builder import (
    OBSTACLE_PREFIX,
    SpecOptions,
    build_spec,
    contact_model,
    count_contacts,
    prepare_urdf_xml,
    replay_contacts,
)


@pytest.fixture(scope="module")
def robot():
    return load_lbr4p()


@pytest.fixture(scope="module")
def arm(tmp_path_factory) -> RobotModel:
    """The LBR4p with its first joint continuous (as in tests/model/test_pinocchio_model.py)."""
    path = tmp_path_factory.mktemp("continuous") / "lbr4p_continuous.urdf"
    path.write_text(_first_joint_continuous(lbr4p_urdf_path().read_text()))
    return RobotModel.from_urdf(path, "lbr4p_flange")


class Replay:
    """The robot's MuJoCo model with obstacles; configurations set and contacts counted."""

    def __init__(self, robot, obstacles):
        n = robot.nq
        options = SpecOptions(
            0.001, False, np.zeros(n), None, robot.limits.effort_max, 0.0, np.zeros(3),
            tuple(obstacles),
        )  # fmt: skip
        self.model = build_spec(robot, prepare_urdf_xml(robot.source), options).compile()
        self.data = mujoco.MjData(self.model)
        joint = mujoco.mjtObj.mjOBJ_JOINT
        self.adr = [
            self.model.jnt_qposadr[mujoco.mj_name2id(self.model, joint, j)]
            for j in robot.joint_names
        ]

    def contacts(self, qs):
        """(robot–obstacle contacts, self contacts, deepest penetration [m]) over ``qs``."""
        obstacle = self_contact = 0
        deepest = 0.0
        for q in np.atleast_2d(qs):
            self.data.qpos[self.adr] = q
            mujoco.mj_forward(self.model, self.data)
            found = count_contacts(self.model, self.data)
            obstacle += found.obstacle
            self_contact += found.self_contact
            deepest = max(deepest, found.deepest_m)
        return obstacle, self_contact, deepest


def test_obstacles_become_named_static_geoms(robot):
    shapes = (
        Sphere(name="ball", position_m=(0.5, 0.0, 0.6), radius_m=0.05),
        Box(name="crate", position_m=(0.3, -0.5, 0.4), size_m=(0.2, 0.1, 0.3)),
        Capsule(name="pole", position_m=(-0.4, 0.3, 0.8), radius_m=0.04, length_m=0.5),
        Cylinder(name="drum", position_m=(0.0, 0.6, 0.4), radius_m=0.1, length_m=0.3),
        HalfSpace(name="floor", normal=(0.0, 0.0, 1.0), offset_m=0.0),
    )
    model = Replay(robot, shapes).model
    geom = mujoco.mjtObj.mjOBJ_GEOM
    for obs in shapes:
        g = mujoco.mj_name2id(model, geom, OBSTACLE_PREFIX + obs.name)
        assert g >= 0 and model.geom_bodyid[g] == 0  # on the world body
    box = mujoco.mj_name2id(model, geom, OBSTACLE_PREFIX + "crate")
    assert np.allclose(model.geom_size[box], [0.1, 0.05, 0.15])  # half sizes
    pole = mujoco.mj_name2id(model, geom, OBSTACLE_PREFIX + "pole")
    assert np.allclose(model.geom_size[pole][:2], [0.04, 0.25])


@pytest.mark.parametrize(
    "obstacle",
    [
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.65),
        HalfSpace(name="wall", normal=(-1.0, 0.0, 0.0), offset_m=-0.52),
        "ball",
    ],
)
def test_mujoco_penetration_matches_the_distance(robot, obstacle):
    """Where a shape enters an obstacle, MuJoCo's deepest penetration is coal's distance."""
    if obstacle == "ball":  # 5 mm into the wrist's sphere, from the side
        wrist = robot.placement(LBR4P_Q0, "lbr4p_link_6").translation
        centre = wrist + np.array([0.0, -1.0, 0.0]) * (0.06 + 0.04 - 0.005)
        obstacle = Sphere(name="ball", position_m=tuple(centre), radius_m=0.04)
    cm = CollisionModel(robot, (obstacle,), self_collision=False)
    distance = cm.min_distance(LBR4P_Q0)
    assert distance < 0.0
    count, self_count, deepest = Replay(robot, cm.obstacles).contacts(LBR4P_Q0)
    assert count > 0 and self_count == 0
    assert deepest == pytest.approx(-distance, abs=1e-4)


def test_replay_contacts_sums_the_contacts_of_each_configuration(robot):
    """``replay_contacts`` over several configurations is the per-configuration count of the
    robot's model built here, summed (the deepest penetration the largest)."""
    plane = HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.6)
    rng = np.random.default_rng(5)
    qs = LBR4P_Q0 + 0.05 * rng.standard_normal((4, robot.nq))
    replay = Replay(robot, (plane,))
    per_q = [replay.contacts(q) for q in qs]
    counted = replay_contacts(robot, (plane,), qs)
    assert counted.obstacle == sum(c[0] for c in per_q) > 0
    assert counted.self_contact == sum(c[1] for c in per_q)
    assert counted.deepest_m == max(c[2] for c in per_q) > 0.0


def test_the_contact_model_addresses_the_robots_joints_by_name(robot):
    model, data, adr = contact_model(robot, ())
    joint = mujoco.mjtObj.mjOBJ_JOINT
    for name, address in zip(robot.joint_names, adr, strict=True):
        assert model.jnt_qposadr[mujoco.mj_name2id(model, joint, name)] == address
    data.qpos[adr] = LBR4P_Q0
    mujoco.mj_forward(model, data)
    assert count_contacts(model, data).obstacle == 0  # no obstacle: none with the world


def test_mujoco_hinge_of_a_continuous_joint_is_unlimited(arm, lbr4p):
    sim = MujocoSimulation(arm)
    assert not sim.model.jnt_limited[0] and sim.model.jnt_limited[1:].all()
    assert MujocoSimulation(lbr4p).model.jnt_limited.all()
    state = sim.reset(np.r_[4.0, LBR4P_Q0[1:]])  # an angle beyond π is a state like any other
    np.testing.assert_allclose(state.q[0], 4.0)


# ----------------------------------------------------------------------------- concave meshes
def _world_vertices(model, data, geom: int) -> np.ndarray:
    """The vertices of mesh geom ``geom`` in the world [m]."""
    mesh = model.geom_dataid[geom]
    start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    local = model.mesh_vert[start : start + count]
    return local @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]


def test_a_concave_collision_mesh_becomes_its_convex_parts_in_place(tmp_path, monkeypatch):
    pytest.importorskip("coacd")
    from scipy.spatial import ConvexHull
    from sim.voxel_meshes import L_SHAPE, voxel_triangles, write_stl

    from dqcontrol.sim.convex_parts import CACHE_ENV
    from dqcontrol.sim.mjcf_builder import _split_concave_meshes

    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    path = write_stl(tmp_path / "l.stl", voxel_triangles(L_SHAPE))
    spec = mujoco.MjSpec.from_string(f"""
        <mujoco><asset><mesh name="l" file="{path}" scale="1 2 1"/></asset>
        <worldbody><body name="link" pos="0.3 -0.2 0.5" euler="10 20 30">
          <geom name="hit" type="mesh" mesh="l" pos="0.05 0 0" euler="0 0 40" friction="0.3 0 0"/>
          <geom name="look" type="mesh" mesh="l" contype="0" conaffinity="0" group="1"/>
        </body></worldbody></mujoco>""")
    _split_concave_meshes(spec)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    names = [model.geom(g).name for g in range(model.ngeom)]
    parts = [g for g, name in enumerate(names) if name.startswith("hit_part")]
    assert "hit" not in names and "look" in names and len(parts) >= 2
    assert all(model.geom_contype[g] == 1 and model.geom_group[g] == 0 for g in parts)
    np.testing.assert_allclose(model.geom_friction[parts, 0], 0.3)
    # the parts are where the mesh was: the whole mesh, placed as the geom they replaced,
    # lies in their union
    spec2 = mujoco.MjSpec.from_string(f"""
        <mujoco><asset><mesh name="l" file="{path}" scale="1 2 1"/></asset>
        <worldbody><body name="link" pos="0.3 -0.2 0.5" euler="10 20 30">
          <geom name="hit" type="mesh" mesh="l" pos="0.05 0 0" euler="0 0 40"/>
        </body></worldbody></mujoco>""")
    whole = spec2.compile()
    whole_data = mujoco.MjData(whole)
    mujoco.mj_forward(whole, whole_data)
    mesh_points = _world_vertices(whole, whole_data, 0)
    hulls = [ConvexHull(_world_vertices(model, data, g)) for g in parts]
    beyond = np.full(len(mesh_points), np.inf)
    for hull in hulls:
        eq = hull.equations
        beyond = np.minimum(beyond, (mesh_points @ eq[:, :3].T + eq[:, 3]).max(axis=1))
    assert beyond.max() <= 5e-5
    assert sum(h.volume for h in hulls) == pytest.approx(2 * 3 * 0.1**3, rel=0.05)


def test_a_robot_of_convex_meshes_keeps_its_geoms():
    from dqcontrol.model import load_panda

    panda = load_panda()
    model = contact_model(panda, ())[0]
    names = [model.geom(g).name for g in range(model.ngeom)]
    assert not any("_part" in name for name in names)
