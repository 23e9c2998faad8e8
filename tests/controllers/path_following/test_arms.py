"""The path-following controller's defaults on an arm other than the LBR4p: the xArm7 from
the start near the vertical, whose circle passes close to a singular configuration
(``σ_min`` 0.025 of the tangent Jacobian near the elbow's stretch, docs/theory.md §8.3).

With the damped-least-squares rows in the path level, the path gave way near that pass:
0.64 mm at T = 50 ms in the kinematic loop, 1.8 mm in MuJoCo at T = 10 ms (with the arm's
own contacts off). This circle also brings link 5 to within a few millimetres of link 1: in
MuJoCo, whose mesh hulls touch there, the arm pushes against itself at its effort limit
(docs/arms.md), which no controller setting removes; the MuJoCo test below turns the
robot's contacts off to judge the controller, and a second test checks that contact is the
cause the docs name.
"""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.cli.robot_options import RobotRequest, load_robot
from dqcontrol.controllers.path_following import PathFollowingController
from dqcontrol.experiments.runner import simulate
from dqcontrol.trajectories import Circle

#: The start near the vertical.
XARM7_Q0 = np.array([0.0, 0.0, 0.0, 0.5, 0.0, 0.5, 0.0])


@pytest.fixture(scope="module")
def xarm7():
    pytest.importorskip("example_robot_data")
    return load_robot(RobotRequest("erd:xarm7", "link_eef"))[0]


def test_xarm7_circle_keeps_the_path_in_the_kinematic_loop(xarm7):
    controller = PathFollowingController(xarm7, Circle(2.0), 0.05)
    m = simulate(controller, XARM7_Q0, "kinematic").result.metrics
    assert m.completed
    assert m.path_deviation_max_m <= 0.1e-3
    assert m.position_violations == m.velocity_violations == 0


def _mujoco(robot, contacts: bool):
    mujoco = pytest.importorskip("mujoco")
    from dqcontrol.sim.mujoco_sim import MujocoSimulation

    sim = MujocoSimulation(robot)
    if not contacts:
        sim.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    return sim


def test_xarm7_circle_keeps_the_path_in_mujoco_at_10_ms(xarm7):
    from dqcontrol.sim.mujoco_sim import SERVO_TIME_CONSTANT_S

    controller = PathFollowingController(
        xarm7, Circle(2.0), 0.01, servo_time_constant_s=SERVO_TIME_CONSTANT_S
    )
    sim = _mujoco(xarm7, contacts=False)
    m = simulate(controller, XARM7_Q0, simulation=sim).result.metrics
    assert m.completed
    assert m.path_deviation_max_m <= 0.5e-3
    assert m.position_violations == m.velocity_violations == 0
    assert m.execution_time_s <= 1.3 * 2.0


def test_the_xarm7_circle_touches_link_1_with_link_5_in_mujoco(xarm7):
    import mujoco

    sim = _mujoco(xarm7, contacts=True)
    # the configuration the circle passes where the elbow is nearly stretched (sampled from
    # a run of the test above)
    q = np.array([0.2023, -1.0710, -0.5603, -0.1422, -0.6162, 0.9540, 0.3030])
    sim.reset(q)
    mujoco.mj_forward(sim.model, sim.data)
    bodies = {
        frozenset(
            mujoco.mj_id2name(sim.model, mujoco.mjtObj.mjOBJ_BODY, sim.model.geom_bodyid[g])
            for g in (c.geom1, c.geom2)
        )
        for c in sim.data.contact[: sim.data.ncon]
    }
    assert frozenset({"link1", "link5"}) in bodies
