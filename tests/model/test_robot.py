"""``dqcontrol.model.robot.RobotModel``: kinematics and dynamics against independent references,
and its input checks.

* LBR4p pose and pose Jacobian against the independent standard-DH code of
  ``tests/dh_reference.py`` (thesis eq. 4.2–4.3), which uses neither Pinocchio nor dqcontrol.
* Pose Jacobians of both robots against central finite differences of ``model.pose``.
* Batched against single calls (also on the benchmark's 14-joint chain); base and tool
  offsets; the limits read from the URDFs.
* Mass matrix, gravity and dynamics-aware acceleration limits against Pinocchio's RNEA.
* The same URDF compiled by MuJoCo puts the flange where Pinocchio does.
* Bad joint vectors, transforms, frames and settings: each a dqcontrol error naming it.

Every random draw is seeded.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import dh_reference as dh
import numpy as np
import pinocchio as pin
import pytest

import dqcontrol
from dqcontrol.cli.bench_cmd import load_bench
from dqcontrol.dq.algebra import (
    align_sign,
    dq_from_matrix,
    dq_from_rt,
    dq_is_unit,
    dq_mul,
    haminus8,
    hamiplus8,
    qfrom_axis_angle,
    qfrom_matrix,
)
from dqcontrol.errors import ConfigurationError, FrameError, ParameterError
from dqcontrol.model.library import LBR4P_Q0, PANDA_Q0, lbr4p_urdf_path, panda_urdf_path

#: the synthetic serial chains of the benchmark (benchmarks/bench.py)
long_chain_urdf = load_bench().long_chain_urdf


def random_q(model: dqcontrol.RobotModel, count: int, seed: int) -> np.ndarray:
    """``count`` configurations drawn uniformly within the model's joint limits."""
    rng = np.random.default_rng(seed)
    return rng.uniform(model.limits.q_min, model.limits.q_max, size=(count, model.nq))


def signed_error(x: np.ndarray, reference: np.ndarray) -> float:
    """``min(‖x - ref‖∞, ‖x + ref‖∞)``: x and -x are the same pose."""
    return min(np.abs(x - reference).max(), np.abs(x + reference).max())


def random_transform(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    T = np.eye(4)
    T[:3, :3] = pin.Quaternion(*qfrom_axis_angle(axis, rng.uniform(0.2, 3.0))).toRotationMatrix()
    T[:3, 3] = rng.uniform(-0.5, 0.5, size=3)
    return T


def fd_pose_jacobian(model: dqcontrol.RobotModel, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences of ``model.pose``, every sample sign-aligned to the centre pose
    (``pose`` picks ``r_w ≥ 0``, which jumps where ``r_w`` crosses 0)."""
    x0 = model.pose(q)
    return dh.finite_difference_jacobian(lambda qq: align_sign(model.pose(qq), x0)[0], q, h)


# =========================================================================== LBR4p vs DH
def test_lbr4p_at_zero_is_the_stretched_arm(lbr4p):
    x = lbr4p.pose(np.zeros(7))
    np.testing.assert_allclose(
        x, dq_from_rt([1.0, 0, 0, 0], dh.LBR4P_FLANGE_AT_ZERO), rtol=0, atol=1e-15
    )
    assert lbr4p.ee_frame == "lbr4p_flange"
    assert lbr4p.nq == 7


def test_lbr4p_poses_equal_dh_reference(lbr4p):
    """≥ 1000 seeded configurations within the limits, batched and single, to 1e-12."""
    qs = random_q(lbr4p, 1000, seed=20240601)
    poses = lbr4p.poses(qs)
    assert poses.shape == (1000, 8)
    worst_batch = worst_single = 0.0
    for q, x_batch in zip(qs, poses, strict=True):
        ref = dh.lbr4p_pose_vec8(q)
        worst_batch = max(worst_batch, signed_error(x_batch, ref))
        worst_single = max(worst_single, signed_error(lbr4p.pose(q), ref))
    assert worst_batch <= 1e-12
    assert worst_single <= 1e-12
    assert all(dq_is_unit(x, 1e-12) for x in poses)
    assert (poses[:, 0] >= 0.0).all()  # documented sign choice: r_w ≥ 0


def test_lbr4p_placement_equals_dh_frames(lbr4p):
    """Also as 4×4 matrices (no quaternion conversion involved on either side)."""
    for q in random_q(lbr4p, 100, seed=7):
        np.testing.assert_allclose(
            lbr4p.placement(q).homogeneous, dh.lbr4p_fkm(q), rtol=0, atol=1e-12
        )
        # frame of link 0 is DH frame 0, 0.51 m above the base
        np.testing.assert_allclose(
            lbr4p.placement(q, "lbr4p_link_0").homogeneous,
            dh.lbr4p_frames(q)[0],
            rtol=0,
            atol=1e-15,
        )


def test_lbr4p_pose_jacobian_equals_dh_pose_jacobian(lbr4p):
    """The DH chain's own product-rule pose Jacobian (no geometric Jacobian involved)."""
    worst_x = worst_j = 0.0
    for q in random_q(lbr4p, 200, seed=314):
        x, jac = lbr4p.pose_and_jacobian(q)
        ref_x = dh.lbr4p_pose_vec8(q)
        ref_j = dh.lbr4p_pose_jacobian_vec8(q)
        sign = 1.0 if np.dot(x, ref_x) >= 0.0 else -1.0
        worst_x = max(worst_x, np.abs(sign * x - ref_x).max())
        worst_j = max(worst_j, np.abs(sign * jac - ref_j).max())
    assert worst_x <= 1e-12
    assert worst_j <= 1e-12


def test_lbr4p_frame_jacobian_equals_dh_geometric_jacobian(lbr4p):
    """The 6×n Jacobian the pose Jacobian is built from (LOCAL_WORLD_ALIGNED, rows [v; w])."""
    model, data = lbr4p.model, lbr4p.model.createData()
    fid = model.getFrameId("lbr4p_flange")
    for q in random_q(lbr4p, 50, seed=5):
        j6 = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(j6, dh.lbr4p_geometric_jacobian(q), rtol=0, atol=1e-12)


# =========================================================================== finite differences
@pytest.mark.parametrize("robot", ["lbr4p", "panda"])
def test_pose_jacobian_matches_finite_differences(robot, request):
    model = request.getfixturevalue(robot)
    qs = random_q(model, 20, seed=99)
    for q in np.vstack([qs, LBR4P_Q0 if robot == "lbr4p" else PANDA_Q0]):
        x, jac = model.pose_and_jacobian(q)
        np.testing.assert_allclose(x, model.pose(q), rtol=0, atol=1e-15)
        np.testing.assert_allclose(jac, model.pose_jacobian(q), rtol=0, atol=0)
        np.testing.assert_allclose(jac, fd_pose_jacobian(model, q), rtol=0, atol=1e-8)


def test_pose_jacobian_across_the_w_sign_switch(lbr4p):
    """Joint 1 alone turns the flange about z: at q1 = π (half-turn) r_w crosses 0 and the
    pose's sign convention flips x; the Jacobian must flip with it (it is ∂vec8(x)/∂q of the
    x actually returned)."""
    for q1 in (np.pi - 1e-3, np.pi + 1e-3, -np.pi + 1e-3):
        q = np.array([q1, 0.3, 0.0, -1.0, 0.0, 0.5, 0.0])
        x, jac = lbr4p._pose_and_jacobian(q)
        assert x[0] >= 0.0
        np.testing.assert_allclose(jac, fd_pose_jacobian(lbr4p, q, 1e-7), rtol=0, atol=1e-7)


@pytest.mark.parametrize("robot", ["lbr4p", "panda"])
def test_the_pose_alone_is_the_pose_of_pose_and_jacobian(robot, request):
    """The kinematics without the Jacobian (``pose``, the unchecked ``fast.pose``) give
    the pose ``pose_and_jacobian`` gives, bit for bit, whatever was computed before."""
    model = request.getfixturevalue(robot)
    qs = random_q(model, 20, seed=77)
    for q, other in zip(qs, qs[::-1], strict=True):
        x = model.pose_and_jacobian(q)[0]
        model.pose_and_jacobian(other)  # the shared data now hold another configuration
        assert np.array_equal(model.fast.pose(q), x)
        assert np.array_equal(model.pose(q), x)


# =========================================================================== batched
@pytest.mark.parametrize("robot", ["lbr4p", "panda"])
@pytest.mark.parametrize("count", [1, 6, 10, 64])
def test_batched_equals_single(robot, count, request):
    model = request.getfixturevalue(robot)
    qs = random_q(model, count, seed=1000 + count)
    xs, jacs = model.poses_and_jacobians(qs)
    assert xs.shape == (count, 8)
    assert jacs.shape == (count, 8, model.nq)
    for i, q in enumerate(qs):
        x, jac = model.pose_and_jacobian(q)
        np.testing.assert_allclose(xs[i], x, rtol=0, atol=1e-14)
        np.testing.assert_allclose(jacs[i], jac, rtol=0, atol=1e-14)
    np.testing.assert_allclose(model.poses(qs), xs, rtol=0, atol=1e-14)


def test_batched_with_mixed_quaternion_signs(lbr4p):
    """A batch where Pinocchio's raw quaternion has w < 0 for some rows and not others."""
    qs = np.zeros((6, 7))
    qs[:, 0] = [0.1, 3.0, -3.0, 2.9, -0.5, -2.95]
    xs, jacs = lbr4p.poses_and_jacobians(qs)
    for i, q in enumerate(qs):
        x, jac = lbr4p.pose_and_jacobian(q)
        np.testing.assert_allclose(xs[i], x, rtol=0, atol=1e-14)
        np.testing.assert_allclose(jacs[i], jac, rtol=0, atol=1e-14)
        assert xs[i, 0] >= 0.0


def test_empty_batch(lbr4p):
    xs, jacs = lbr4p.poses_and_jacobians(np.zeros((0, 7)))
    assert xs.shape == (0, 8)
    assert jacs.shape == (0, 8, 7)


@pytest.fixture(scope="module")
def chain14() -> dqcontrol.RobotModel:
    return dqcontrol.RobotModel.from_urdf(long_chain_urdf(14), "flange")


@pytest.mark.parametrize("robot_name", ["lbr4p", "chain14"])
def test_batched_kinematics_equal_single_calls(robot_name, request):
    robot = request.getfixturevalue(robot_name)
    qs = robot.random_configurations(50, seed=3)
    xs, jacs = robot.poses_and_jacobians(qs)
    for q, x, jac in zip(qs, xs, jacs, strict=True):
        x1, jac1 = robot.pose_and_jacobian(q)
        np.testing.assert_allclose(x, x1, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jac, jac1, rtol=0, atol=1e-12)
        assert x[0] >= 0.0  # r_w ≥ 0, as the single path


# =========================================================================== base and tool
BASE_T = random_transform(41)
TOOL_T = random_transform(42)


@pytest.mark.parametrize("form", ["matrix", "se3", "vec8"])
def test_base_and_tool_offsets_compose_as_dual_quaternions(form, lbr4p):
    convert = {
        "matrix": lambda T: T,
        "se3": lambda T: pin.SE3(T),
        "vec8": dq_from_matrix,
    }[form]
    model = dqcontrol.load_lbr4p(base=convert(BASE_T), tool=convert(TOOL_T))
    assert model.ee_frame == "lbr4p_flange_tool"
    xb, xt = dq_from_matrix(BASE_T), dq_from_matrix(TOOL_T)
    for q in random_q(lbr4p, 30, seed=43):
        expected = dq_mul(dq_mul(xb, lbr4p.pose(q)), xt)
        x, jac = model.pose_and_jacobian(q)
        assert signed_error(x, expected) <= 1e-12
        # J_bt = H+8(x_b) H-8(x_t) J, with the same sign as x
        _, jac0 = lbr4p.pose_and_jacobian(q)
        jac_expected = hamiplus8(xb) @ haminus8(xt) @ jac0
        sign = 1.0 if np.dot(x, expected) >= 0.0 else -1.0
        np.testing.assert_allclose(jac, sign * jac_expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            model.placement(q).homogeneous,
            BASE_T @ lbr4p.placement(q).homogeneous @ TOOL_T,
            rtol=0,
            atol=1e-12,
        )


def test_base_and_tool_jacobian_matches_finite_differences(lbr4p):
    model = dqcontrol.load_lbr4p(base=BASE_T, tool=TOOL_T)
    for q in random_q(lbr4p, 10, seed=44):
        _, jac = model.pose_and_jacobian(q)
        np.testing.assert_allclose(jac, fd_pose_jacobian(model, q), rtol=0, atol=1e-8)


def test_base_offset_on_the_panda(panda):
    model = dqcontrol.load_panda(base=BASE_T)
    xb = dq_from_matrix(BASE_T)
    for q in random_q(panda, 10, seed=45):
        assert signed_error(model.pose(q), dq_mul(xb, panda.pose(q))) <= 1e-12
        np.testing.assert_allclose(
            model.pose_jacobian(q), fd_pose_jacobian(model, q), rtol=0, atol=1e-8
        )


def test_offsets_do_not_change_the_shared_robot(lbr4p):
    q = LBR4P_Q0
    before = lbr4p.pose(q)
    dqcontrol.load_lbr4p(base=BASE_T, tool=TOOL_T)
    np.testing.assert_array_equal(lbr4p.pose(q), before)
    np.testing.assert_allclose(lbr4p.pose(q), dh.lbr4p_pose_vec8(q), rtol=0, atol=1e-12)


# =========================================================================== Panda
def _urdf_limits(path, names):
    root = ET.parse(path).getroot()
    joints = {j.get("name"): j for j in root.findall("joint")}
    limits = [joints[n].find("limit") for n in names]
    return {
        key: np.array([float(lim.get(key)) for lim in limits])
        for key in ("lower", "upper", "velocity", "effort")
    }


def test_panda_limits_equal_the_urdf(panda):
    path, _ = panda_urdf_path()
    urdf = _urdf_limits(path, panda.joint_names)
    np.testing.assert_array_equal(panda.limits.q_min, urdf["lower"])
    np.testing.assert_array_equal(panda.limits.q_max, urdf["upper"])
    np.testing.assert_array_equal(panda.limits.qd_max, urdf["velocity"])
    np.testing.assert_array_equal(panda.limits.effort_max, urdf["effort"])


def test_lbr4p_limits_equal_the_urdf(lbr4p):
    urdf = _urdf_limits(lbr4p_urdf_path(), lbr4p.joint_names)
    np.testing.assert_array_equal(lbr4p.limits.q_min, urdf["lower"])
    np.testing.assert_array_equal(lbr4p.limits.q_max, urdf["upper"])
    np.testing.assert_array_equal(lbr4p.limits.qd_max, urdf["velocity"])
    np.testing.assert_array_equal(lbr4p.limits.effort_max, urdf["effort"])
    # README: ±170° (1, 3, 5, 7), ±120° (2, 4, 6); 176, 176, 100, 100, 100, 38, 38 N·m
    deg = np.deg2rad([170, 120, 170, 120, 170, 120, 170])
    np.testing.assert_allclose(lbr4p.limits.q_max, deg, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lbr4p.limits.q_min, -deg, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(lbr4p.limits.effort_max, [176, 176, 100, 100, 100, 38, 38])


# =========================================================================== dynamics
@pytest.mark.parametrize("robot", ["lbr4p", "panda"])
def test_mass_matrix_is_symmetric_positive_definite_and_matches_rnea(robot, request):
    model = request.getfixturevalue(robot)
    data = model.model.createData()
    zero = np.zeros(model.nq)
    for q in random_q(model, 20, seed=77):
        m = model.mass_matrix(q)
        np.testing.assert_array_equal(m, m.T)
        assert np.linalg.eigvalsh(m).min() > 0.0
        g = pin.rnea(model.model, data, q, zero, zero)
        for j in range(model.nq):  # column j of M = τ(q, 0, e_j) - g(q)
            e_j = np.eye(model.nq)[j]
            col = pin.rnea(model.model, data, q, zero, e_j) - g
            np.testing.assert_allclose(m[:, j], col, rtol=0, atol=1e-12)


@pytest.mark.parametrize("robot", ["lbr4p", "panda"])
def test_gravity_matches_rnea(robot, request):
    model = request.getfixturevalue(robot)
    data = model.model.createData()
    zero = np.zeros(model.nq)
    for q in random_q(model, 20, seed=78):
        g = model.gravity(q)
        np.testing.assert_allclose(g, pin.rnea(model.model, data, q, zero, zero), atol=1e-12)
        # an independent formula: g = -m_total Jcomᵀ g0 (g0 = [0, 0, -9.81] m/s²)
        jcom = pin.jacobianCenterOfMass(model.model, data, q)
        expected = -data.mass[0] * jcom.T @ model.model.gravity.linear
        np.testing.assert_allclose(g, expected, rtol=0, atol=1e-10)


def test_lbr4p_gravity_on_vertical_first_axis_is_zero(lbr4p):
    for q in random_q(lbr4p, 20, seed=79):
        assert abs(lbr4p.gravity(q)[0]) <= 1e-12
    # stretched arm upright: no gravity torque at all
    np.testing.assert_allclose(lbr4p.gravity(np.zeros(7)), np.zeros(7), rtol=0, atol=1e-12)


def test_lbr4p_moving_mass(lbr4p):
    model = lbr4p.model
    moving = sum(model.inertias[j].mass for j in range(1, model.njoints))
    assert moving == pytest.approx(14.4, abs=1e-9)
    masses = [model.inertias[j].mass for j in range(1, model.njoints)]
    np.testing.assert_allclose(masses, [2.7, 2.7, 2.7, 2.7, 1.7, 1.6, 0.3], rtol=0, atol=1e-9)


@pytest.mark.parametrize("robot", ["lbr4p", "panda"])
@pytest.mark.parametrize(("fraction", "floor", "cap"), [(1.0, 0.5, 50.0), (0.3, 2.0, 30.0)])
def test_acceleration_limits_formula_and_clipping(robot, fraction, floor, cap, request):
    model = request.getfixturevalue(robot)
    clipped_low = clipped_high = unclipped = 0
    for q in random_q(model, 30, seed=80):
        amax = model.acceleration_limits(
            q, effort_fraction=fraction, floor_rad_s2=floor, cap_rad_s2=cap
        )
        assert amax.shape == (model.nq,)
        assert (amax >= floor).all() and (amax <= cap).all()
        m = model.mass_matrix(q)
        g = model.gravity(q)
        formula = (fraction * model.limits.effort_max - np.abs(g)) / np.diag(m)
        inside = (formula > floor) & (formula < cap)
        np.testing.assert_allclose(amax[inside], formula[inside], rtol=1e-12, atol=0)
        np.testing.assert_array_equal(amax[formula <= floor], floor)
        np.testing.assert_array_equal(amax[formula >= cap], cap)
        clipped_low += int((formula <= floor).sum())
        clipped_high += int((formula >= cap).sum())
        unclipped += int(inside.sum())
    assert unclipped > 0
    assert clipped_high > 0  # the light wrist joints reach the cap


def test_acceleration_limits_default_arguments(lbr4p):
    q = LBR4P_Q0
    np.testing.assert_array_equal(
        lbr4p.acceleration_limits(q),
        lbr4p.acceleration_limits(q, effort_fraction=1.0, floor_rad_s2=0.5, cap_rad_s2=50.0),
    )


# =========================================================================== MuJoCo
def test_mujoco_flange_matches_pinocchio(lbr4p):
    mujoco = pytest.importorskip("mujoco")
    mj_model = mujoco.MjModel.from_xml_path(str(lbr4p_urdf_path()))
    mj_data = mujoco.MjData(mj_model)
    adr = [mj_model.joint(name).qposadr[0] for name in lbr4p.joint_names]
    assert mj_model.nq == 7
    body = mj_model.body("lbr4p_flange").id
    for q in random_q(lbr4p, 50, seed=2718):
        mj_data.qpos[:] = 0.0
        mj_data.qpos[adr] = q
        mujoco.mj_kinematics(mj_model, mj_data)
        placement = lbr4p.placement(q)
        np.testing.assert_allclose(mj_data.xpos[body], placement.translation, rtol=0, atol=1e-9)
        r_pin = qfrom_matrix(placement.rotation)
        assert signed_error(mj_data.xquat[body], r_pin) <= 1e-9
        np.testing.assert_allclose(
            mj_data.xmat[body].reshape(3, 3), placement.rotation, rtol=0, atol=1e-9
        )


# =========================================================================== bad input
def test_unknown_end_effector_frame_lists_the_frames():
    with pytest.raises(FrameError, match="unknown end-effector frame 'tool0'") as info:
        dqcontrol.RobotModel.from_urdf(lbr4p_urdf_path(), "tool0")
    assert "lbr4p_flange" in str(info.value)
    assert isinstance(info.value, KeyError)  # usable where a KeyError is expected


def test_unknown_frame_query(lbr4p):
    with pytest.raises(FrameError, match="unknown frame 'nope'") as info:
        lbr4p.placement(LBR4P_Q0, "nope")
    assert "lbr4p_flange" in str(info.value)
    assert str(info.value).startswith("unknown frame")  # not KeyError's quoted repr


def _robot_calls(model):
    return {
        "pose": model.pose,
        "pose_and_jacobian": model.pose_and_jacobian,
        "pose_jacobian": model.pose_jacobian,
        "placement": model.placement,
        "mass_matrix": model.mass_matrix,
        "gravity": model.gravity,
        "acceleration_limits": model.acceleration_limits,
    }


CALLS = list(_robot_calls(dqcontrol.RobotModel).keys())


@pytest.mark.parametrize("call", CALLS)
@pytest.mark.parametrize("q", [np.zeros(6), np.zeros(8), np.zeros((1, 7)), 0.0, []])
def test_q_of_wrong_size(lbr4p, call, q):
    with pytest.raises(ConfigurationError, match=re.escape("must have shape (7,)")) as info:
        _robot_calls(lbr4p)[call](q)
    assert f"got shape {np.shape(q)}" in str(info.value)
    assert "lbr4p_joint_1" in str(info.value)  # names the joints expected


@pytest.mark.parametrize("call", CALLS)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_q_not_finite(lbr4p, call, bad):
    q = LBR4P_Q0.copy()
    q[3] = bad
    with pytest.raises(ConfigurationError, match="must be finite"):
        _robot_calls(lbr4p)[call](q)


@pytest.mark.parametrize("call", ["poses", "poses_and_jacobians"])
@pytest.mark.parametrize("shape", [(10, 6), (7,), (2, 3, 7), (7, 10)])
def test_batch_of_wrong_shape(lbr4p, call, shape):
    with pytest.raises(ConfigurationError, match=re.escape("must have shape (N, 7)")) as info:
        getattr(lbr4p, call)(np.zeros(shape))
    assert f"got shape {shape}" in str(info.value)


@pytest.mark.parametrize("call", ["poses", "poses_and_jacobians"])
def test_batch_not_finite(lbr4p, call):
    qs = np.zeros((4, 7))
    qs[2, 5] = np.nan
    with pytest.raises(ConfigurationError, match="must be finite"):
        getattr(lbr4p, call)(qs)


def _not_orthonormal() -> np.ndarray:
    T = np.eye(4)
    T[0, 0] = 2.0
    return T


def _reflection() -> np.ndarray:
    T = np.eye(4)
    T[2, 2] = -1.0
    return T


def _nan_transform() -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = np.nan
    return T


BAD_TRANSFORMS = {
    "not orthonormal": _not_orthonormal(),
    "reflection": _reflection(),
    "nan": _nan_transform(),
    "3x3": np.eye(3),
    "non-unit vec8": 2.0 * dq_from_rt([1.0, 0, 0, 0], [0.1, 0, 0]),
    "vec8 with dual part not orthogonal": np.array([1.0, 0, 0, 0, 0.3, 0, 0, 0]),
}


@pytest.mark.parametrize("which", ["base", "tool"])
@pytest.mark.parametrize("name", list(BAD_TRANSFORMS))
def test_bad_base_or_tool_transform(which, name):
    with pytest.raises(ParameterError, match=f"{which} must be a pin.SE3, a 4×4"):
        dqcontrol.load_lbr4p(**{which: BAD_TRANSFORMS[name]})


@pytest.mark.parametrize("which", ["base", "tool"])
@pytest.mark.parametrize("value", ["identity", object()], ids=["str", "object"])
def test_non_numeric_base_or_tool(which, value):
    with pytest.raises(ParameterError, match=f"{which} must be a pin.SE3, a 4×4"):
        dqcontrol.load_lbr4p(**{which: value})


@pytest.mark.parametrize("q", ["abc", ["a"] * 7, [0, 0, 0, 0, 0, 0, [0]]], ids=str)
def test_non_numeric_q(lbr4p, q):
    with pytest.raises(ConfigurationError):
        lbr4p.pose(q)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"effort_fraction": 0.0}, "effort_fraction must be in (0, 1]"),
        ({"effort_fraction": 1.5}, "effort_fraction must be in (0, 1]"),
        ({"floor_rad_s2": 0.0}, "need 0 < floor_rad_s2 ≤ cap_rad_s2"),
        ({"floor_rad_s2": 5.0, "cap_rad_s2": 1.0}, "need 0 < floor_rad_s2 ≤ cap_rad_s2"),
    ],
)
def test_bad_acceleration_limit_parameters(lbr4p, kwargs, message):
    with pytest.raises(ParameterError, match=re.escape(message)):
        lbr4p.acceleration_limits(LBR4P_Q0, **kwargs)


def test_check_q_takes_lists_and_names_the_argument(lbr4p):
    q = lbr4p.check_q(list(LBR4P_Q0))
    assert q.dtype == np.float64 and q.shape == (7,)
    np.testing.assert_array_equal(q, LBR4P_Q0)
    with pytest.raises(ConfigurationError, match=re.escape("qd0 must have shape (7,)")):
        lbr4p.check_q(np.zeros(3), name="qd0")


# =========================================================================== sampling
def test_random_configurations_are_seeded_uniform_and_inside_the_margin(lbr4p):
    margin = 0.1
    qs = lbr4p.random_configurations(2000, seed=5, margin_rad=margin)
    assert qs.shape == (2000, 7)
    np.testing.assert_array_equal(qs, lbr4p.random_configurations(2000, seed=5, margin_rad=margin))
    assert not np.array_equal(qs, lbr4p.random_configurations(2000, seed=6, margin_rad=margin))
    lo, hi = lbr4p.limits.q_min + margin, lbr4p.limits.q_max - margin
    assert np.all(qs >= lo) and np.all(qs <= hi)
    # uniform: the sample mean is the middle of the range to a few standard errors
    standard_error = (hi - lo) / np.sqrt(12 * 2000)
    assert np.all(np.abs(qs.mean(axis=0) - 0.5 * (lo + hi)) <= 4 * standard_error)
