"""Obstacles in MuJoCo (docs/theory.md §10.6): the same obstacles added to the robot's MuJoCo
model as static geoms, contacts counted by MuJoCo's own collision detection — an independent
check of the distances and of the runs of tests/controllers/limits/test_collision.py
replayed in it."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from controllers.limits.test_collision import circle_point, closed_loop, make
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dqcontrol import load_lbr4p
from dqcontrol.controllers.limits.collision import CollisionLimit
from dqcontrol.model import LBR4P_Q0
from dqcontrol.model.collision import Box, Capsule, CollisionModel, Cylinder, HalfSpace, Sphere
from dqcontrol.sim.mjcf_builder import (
    OBSTACLE_PREFIX,
    SpecOptions,
    build_spec,
    count_contacts,
    prepare_urdf_xml,
)
from dqcontrol.trajectories import Circle


@pytest.fixture(scope="module")
def robot():
    return load_lbr4p()


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


def test_runs_with_the_limit_make_no_contact(robot):
    ball = Sphere(name="ball", position_m=tuple(circle_point(robot, 1.0)), radius_m=0.03)
    cm = CollisionModel(robot, (ball,))
    replay = Replay(robot, cm.obstacles)
    free = closed_loop(robot, make(robot, "path_following", Circle(2.0)), cm, 2.5)
    assert replay.contacts(free["q"])[0] > 0
    for name in ("path_following", "local"):
        run = closed_loop(robot, make(robot, name, Circle(2.0), (CollisionLimit(cm),)), cm, 3.0)
        assert replay.contacts(run["q"]) == (0, 0, 0.0)


@settings(
    max_examples=4,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    phase=st.floats(0.3, 1.9),
    offset=st.lists(st.floats(-0.06, 0.06), min_size=3, max_size=3),
    radius=st.floats(0.02, 0.06),
)
def test_fuzz_no_contact_in_mujoco(robot, phase, offset, radius):
    centre = circle_point(robot, phase) + np.array(offset)
    ball = Sphere(name="ball", position_m=tuple(centre), radius_m=radius)
    cm = CollisionModel(robot, (ball,))
    if cm.min_distance(LBR4P_Q0) < 0.03:
        return  # a start inside the margin is not this test's case
    run = closed_loop(
        robot, make(robot, "path_following", Circle(2.0), (CollisionLimit(cm),)), cm, 2.5
    )
    assert Replay(robot, cm.obstacles).contacts(run["q"])[:2] == (0, 0)
    assert not math.isnan(run["d_min"].min())


def test_the_folding_task_has_no_self_contact_with_the_limit(robot):
    from controllers.limits.test_collision import fold_task

    cm = CollisionModel(robot)
    replay = Replay(robot, ())
    task = fold_task(robot)
    free = closed_loop(robot, make(robot, "path_following", task), cm, 5.0)
    assert replay.contacts(free["q"])[1] > 0  # MuJoCo sees the wrist in the pedestal
    run = closed_loop(robot, make(robot, "path_following", task, (CollisionLimit(cm),)), cm, 5.0)
    assert replay.contacts(run["q"]) == (0, 0, 0.0)


def test_the_simulation_collides_with_its_obstacles(robot):
    """An obstacle given to the simulator is a body the arm hits: a ball on the flange
    stops it where the same command without the ball moves it."""
    import pinocchio as pin

    from dqcontrol.model import LBR4P_Q0
    from dqcontrol.sim import MujocoSimulation

    flange = robot.placement(LBR4P_Q0).translation
    ball = Sphere(name="ball", position_m=tuple(flange + [0.0, 0.0, -0.08]), radius_m=0.05)
    moved = {}
    for shapes in ((), (ball,)):
        sim = MujocoSimulation(robot, obstacles=shapes)
        sim.reset(LBR4P_Q0)
        jac = pin.computeFrameJacobian(
            robot.model, robot.data, LBR4P_Q0, robot.frame_id(robot.ee_frame),
            pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
        )  # fmt: skip
        down = np.linalg.pinv(jac[:3]) @ np.array([0.0, 0.0, -0.1])  # 0.1 m/s down [rad/s]
        for _ in range(20):
            meas = sim.step(down, 0.05)
        moved[len(shapes)] = float(robot.placement(meas.q).translation[2] - flange[2])
    assert moved[0] < -0.05  # free: the flange goes down by more than the gap
    assert moved[1] > -0.05  # with the ball: stopped by it
