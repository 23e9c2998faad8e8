"""``dqcontrol.model.pinocchio_model``: continuous joints as one angle (against the LBR4p,
Pinocchio's cos/sin model, finite differences, closed loops past ±π) and locked joints."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import dqcontrol
from dqcontrol.dq.algebra import dq_from_rt, dq_from_se3, dq_mul, qfrom_axis_angle
from dqcontrol.errors import FrameError, URDFError
from dqcontrol.model import LBR4P_Q0, RobotModel, lbr4p_urdf_path
from dqcontrol.model.pinocchio_model import (
    angle_model,
    build_angle_model,
    has_unbounded_joints,
    lock_joints,
)
from dqcontrol.registry import build_controller
from dqcontrol.sim import run_kinematic, run_mujoco
from dqcontrol.trajectories import FunctionTrajectory

_REVOLUTE = 'type="revolute"'


def _first_joint_continuous(xml: str) -> str:
    at = xml.index(_REVOLUTE)
    return xml[:at] + 'type="continuous"' + xml[at + len(_REVOLUTE) :]


@pytest.fixture(scope="module")
def urdf_continuous(tmp_path_factory):
    path = tmp_path_factory.mktemp("continuous") / "lbr4p_continuous.urdf"
    path.write_text(_first_joint_continuous(lbr4p_urdf_path().read_text()))
    return path


@pytest.fixture(scope="module")
def arm(urdf_continuous) -> RobotModel:
    return RobotModel.from_urdf(urdf_continuous, "lbr4p_flange")


def _configurations(count: int, seed: int) -> np.ndarray:
    """Seeded configurations whose first angle ranges over several turns."""
    rng = np.random.default_rng(seed)
    qs = rng.uniform(-2.0, 2.0, size=(count, 7))
    qs[:, 0] = rng.uniform(-3.0 * np.pi, 3.0 * np.pi, size=count)
    return qs


def test_continuous_joint_has_one_angle_and_no_position_limit(arm, lbr4p):
    assert arm.nq == 7 and arm.joint_names == lbr4p.joint_names
    assert arm.limits.q_min[0] == -np.inf and arm.limits.q_max[0] == np.inf
    np.testing.assert_array_equal(arm.limits.q_min[1:], lbr4p.limits.q_min[1:])
    np.testing.assert_array_equal(arm.limits.qd_max, lbr4p.limits.qd_max)
    np.testing.assert_array_equal(arm.limits.effort_max, lbr4p.limits.effort_max)
    qs = arm.random_configurations(50, seed=3)
    assert np.isfinite(qs).all() and np.abs(qs[:, 0]).max() <= np.pi


def test_kinematics_equal_the_revolute_arm_at_the_same_angle(arm, lbr4p):
    for q in _configurations(20, seed=1):
        x, jac = arm.pose_and_jacobian(q)
        x_ref, jac_ref = lbr4p.pose_and_jacobian(q)
        np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jac, jac_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(arm.mass_matrix(q), lbr4p.mass_matrix(q), atol=1e-12)
        np.testing.assert_allclose(arm.gravity(q), lbr4p.gravity(q), atol=1e-10)


def test_kinematics_equal_pinocchios_cos_sin_model(urdf_continuous, arm):
    """The angle θ of our model is Pinocchio's configuration (cos θ, sin θ)."""
    model = pin.buildModelFromUrdf(str(urdf_continuous))
    assert model.nq == 8 and model.nv == 7
    data = model.createData()
    fid = model.getFrameId("lbr4p_flange")
    for q in _configurations(20, seed=2):
        q_pin = np.concatenate(([np.cos(q[0]), np.sin(q[0])], q[1:]))
        pin.framesForwardKinematics(model, data, q_pin)
        x_ref = dq_from_se3(data.oMf[fid])
        x = arm.pose(q)
        np.testing.assert_allclose(x * np.sign(x_ref @ x), x_ref, rtol=0, atol=1e-12)


def test_a_pinocchio_model_with_cos_sin_joints_is_taken_as_angles(urdf_continuous, arm):
    robot = RobotModel(pin.buildModelFromUrdf(str(urdf_continuous)), "lbr4p_flange")
    assert robot.nq == robot.model.nq == 7 and robot.limits.q_max[0] == np.inf
    q = _configurations(1, seed=9)[0]
    np.testing.assert_allclose(robot.pose(q), arm.pose(q), rtol=0, atol=1e-12)


def test_jacobian_matches_finite_differences(arm):
    step = 1e-6
    for q in _configurations(10, seed=4):
        jac = arm.pose_jacobian(q)
        x = arm.pose(q)
        for j in range(arm.nq):
            dq = np.zeros(arm.nq)
            dq[j] = step
            plus, minus = arm.pose(q + dq), arm.pose(q - dq)
            plus *= np.sign(plus @ x)
            minus *= np.sign(minus @ x)
            np.testing.assert_allclose(jac[:, j], (plus - minus) / (2 * step), atol=1e-8)


def test_batch_kinematics_equal_the_single_calls(arm):
    qs = _configurations(12, seed=5)
    xs, jacs = arm.poses_and_jacobians(qs)
    xs_pin, jacs_pin = arm._poses_and_jacobians_pinocchio(qs)
    assert arm._chain is not None  # the closed-form batch applies to the continuous joint
    for i, q in enumerate(qs):
        x, jac = arm.pose_and_jacobian(q)
        np.testing.assert_allclose(xs[i], x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jacs[i], jac, rtol=0, atol=1e-12)
        np.testing.assert_allclose(xs_pin[i], x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jacs_pin[i], jac, rtol=0, atol=1e-12)


_TILTED = """<robot name="tilted">
  <link name="base"/>
  <link name="l1"><inertial><mass value="1"/><origin xyz="0.1 0 0"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><mass value="1"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="{kind}"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1" rpy="0.1 0.2 0.3"/><axis xyz="0 0.6 0.8"/>
    <limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="2"/></joint>
</robot>"""


def test_continuous_joint_about_a_tilted_axis():
    arm = RobotModel.from_urdf(_TILTED.format(kind="continuous"), "l2")
    ref = RobotModel.from_urdf(_TILTED.format(kind="revolute"), "l2")
    assert arm.limits.q_min[0] == -np.inf and ref.limits.q_min[0] == -3.0
    for q in np.random.default_rng(6).uniform(-7.0, 7.0, size=(10, 2)):
        np.testing.assert_allclose(arm.pose(q), ref.pose(q), rtol=0, atol=1e-12)
        np.testing.assert_allclose(arm.pose_jacobian(q), ref.pose_jacobian(q), atol=1e-12)


def test_a_continuous_joint_can_be_locked_at_an_angle(urdf_continuous, arm):
    locked = RobotModel.from_urdf(
        urdf_continuous, "lbr4p_flange", locked_joints={arm.joint_names[0]: 3.5}
    )
    assert locked.nq == 6 and locked.joint_names == arm.joint_names[1:]
    q = LBR4P_Q0.copy()
    q[0] = 3.5
    np.testing.assert_allclose(locked.pose(q[1:]), arm.pose(q), rtol=0, atol=1e-12)


# ---------------------------------------------------------------------- closed loops
_TURN_RAD = 1.0
_DURATION_S = 2.0


def _turn_about_world_z(x0: np.ndarray) -> FunctionTrajectory:
    """The end-effector pose ``x0`` turned by ``_TURN_RAD`` about world z (smooth start/end)."""
    axis = np.array([0.0, 0.0, 1.0])

    def pose(sigma_s: float) -> np.ndarray:
        u = min(max(sigma_s / _DURATION_S, 0.0), 1.0)
        angle_rad = _TURN_RAD * u * u * (3.0 - 2.0 * u)
        return dq_mul(dq_from_rt(qfrom_axis_angle(axis, angle_rad), np.zeros(3)), x0)

    world = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    return FunctionTrajectory(pose, None, _DURATION_S, reference=world)


def _start() -> np.ndarray:
    q0 = LBR4P_Q0.copy()
    q0[0] = 2.8  # 0.34 rad before +π; the turn carries the first joint past it
    return q0


@pytest.mark.parametrize(
    ("name", "solver"), [("local", "daqp"), ("p10", "daqp"), ("p6", "osqp"), ("pf", "daqp")]
)
def test_kinematic_loop_turns_the_continuous_joint_past_pi(arm, name, solver):
    q0 = _start()
    controller = build_controller(name, arm, _turn_about_world_z(arm.pose(q0)), 0.05, solver=solver)
    result = run_kinematic(controller, q0)
    assert result.metrics.completed and result.metrics.fallbacks == 0
    assert np.isfinite(result.log.q).all() and np.isfinite(result.log.qd_command).all()
    assert result.log.q[-1, 0] > np.pi + 0.3
    assert result.metrics.e_max < 5e-3 and result.metrics.position_violations == 0


def test_the_revolute_arm_cannot_make_that_turn(lbr4p):
    q0 = _start()
    controller = build_controller("local", lbr4p, _turn_about_world_z(lbr4p.pose(q0)), 0.05)
    result = run_kinematic(controller, q0)
    assert result.log.q[:, 0].max() <= lbr4p.limits.q_max[0] + 1e-9


@pytest.mark.parametrize("name", ["local", "pf"])
def test_mujoco_turns_the_continuous_joint_past_pi(arm, name):
    q0 = _start()
    controller = build_controller(name, arm, _turn_about_world_z(arm.pose(q0)), 0.01)
    result = run_mujoco(controller, q0)
    assert result.metrics.completed and result.metrics.fallbacks == 0
    assert np.isfinite(result.log.q).all()
    assert result.log.q[-1, 0] > np.pi + 0.3
    assert result.metrics.e_max < 5e-3


def test_collision_distances_equal_the_revolute_arm(arm, lbr4p):
    from dqcontrol.model.collision import CollisionModel, parse_obstacle

    sphere = parse_obstacle("sphere:0.4,-0.3,0.7,0.05", name="ball")
    model = CollisionModel(arm, [sphere], self_collision=True)
    reference = CollisionModel(lbr4p, [sphere], self_collision=True)
    assert model.num_pairs == reference.num_pairs > 0
    for q in _configurations(5, seed=8):
        assert model.min_distance(q) == pytest.approx(reference.min_distance(q), abs=1e-9)


# =========================================================================== locked joints
def test_unknown_locked_joint():
    with pytest.raises(FrameError, match="cannot lock unknown joint 'ghost_joint'") as info:
        dqcontrol.load_panda(locked_joints={"ghost_joint": 0.0})
    assert "panda_joint1" in str(info.value)


def test_locking_a_joint_holds_it_at_its_value(lbr4p):
    """The reduced model's flange at ``q[:6]`` is the full model's at ``(q[:6], 0.3)``."""
    reduced = lock_joints(lbr4p.model, {"lbr4p_joint_7": 0.3})
    assert reduced.nq == 6 and "lbr4p_joint_7" not in list(reduced.names)
    full_data, reduced_data = lbr4p.model.createData(), reduced.createData()
    full_frame = lbr4p.model.getFrameId("lbr4p_flange")
    reduced_frame = reduced.getFrameId("lbr4p_flange")
    for q in lbr4p.random_configurations(5, seed=21):
        q[6] = 0.3
        pin.framesForwardKinematics(lbr4p.model, full_data, q)
        pin.framesForwardKinematics(reduced, reduced_data, q[:6])
        np.testing.assert_allclose(
            reduced_data.oMf[reduced_frame].homogeneous,
            full_data.oMf[full_frame].homogeneous,
            rtol=0,
            atol=1e-14,
        )


def test_locking_nothing_returns_the_model_and_geometry_as_given(lbr4p):
    assert lock_joints(lbr4p.model, {}) is lbr4p.model
    geometry = pin.GeometryModel()
    assert lock_joints(lbr4p.model, {}, geometry) == (lbr4p.model, geometry)
    model, reduced_geometry = lock_joints(lbr4p.model, {"lbr4p_joint_1": 0.0}, geometry)
    assert model.nq == 6 and isinstance(reduced_geometry, pin.GeometryModel)


# =========================================================================== angle models
def test_the_angle_model_replaces_only_the_unbounded_joints(urdf_continuous, lbr4p):
    raw = pin.buildModelFromXML(urdf_continuous.read_text())
    assert has_unbounded_joints(raw) and raw.nq == 8 and raw.nv == 7
    model = angle_model(raw)
    assert not has_unbounded_joints(model) and model.nq == model.nv == 7
    assert list(model.names) == list(raw.names) and model.nframes == raw.nframes
    np.testing.assert_array_equal(model.velocityLimit, raw.velocityLimit)
    np.testing.assert_array_equal(model.effortLimit, raw.effortLimit)
    assert model.lowerPositionLimit[0] == -np.inf and model.upperPositionLimit[0] == np.inf
    np.testing.assert_array_equal(model.upperPositionLimit[1:], raw.upperPositionLimit[2:])
    # a model without such joints is returned as it is
    assert angle_model(lbr4p.model) is lbr4p.model


def test_a_text_pinocchio_cannot_read_is_a_urdf_error():
    with pytest.raises(URDFError, match="Pinocchio could not build a model from the URDF"):
        build_angle_model(
            "<robot name='r'><link name='a'/><joint name='j' type='revolute'/></robot>"
        )
