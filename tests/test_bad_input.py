"""Bad inputs raise the documented error class (all derive from ``DQControlError``) with a
message that says what was wrong.

The URDFs are small strings built here: a two-link arm (``base`` → ``link1`` by the revolute
``joint1``) that loads, and one mutation of it per test.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

import dqcontrol
from dqcontrol.dq.algebra import dq_from_rt, dq_inv, dq_to_se3, qfrom_axis_angle, qfrom_matrix
from dqcontrol.errors import (
    ConfigurationError,
    DQControlError,
    FrameError,
    ParameterError,
    URDFError,
)
from dqcontrol.model.library import LBR4P_Q0, lbr4p_urdf_path

INERTIAL = """
    <inertial>
      <origin xyz="0 0 0.1" rpy="0 0 0"/>
      <mass value="{mass}"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
    </inertial>"""


def make_urdf(
    *,
    root: str = "robot",
    parent: str = "base",
    origin_xyz: str = "0 0 0.2",
    mass: str = "1.0",
    lower: str = "-1.5",
    upper: str = "1.5",
    joint_type: str = "revolute",
) -> str:
    """A two-link arm; every keyword is one place a test can break it."""
    return f"""<?xml version="1.0"?>
<{root} name="tiny">
  <link name="base"/>
  <link name="link1">{INERTIAL.format(mass=mass)}
  </link>
  <link name="tip"/>
  <joint name="joint1" type="{joint_type}">
    <parent link="{parent}"/>
    <child link="link1"/>
    <origin xyz="{origin_xyz}" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="{lower}" upper="{upper}" effort="10" velocity="2"/>
  </joint>
  <joint name="tip_joint" type="fixed">
    <parent link="link1"/>
    <child link="tip"/>
    <origin xyz="0.3 0 0" rpy="0 0 0"/>
  </joint>
</{root}>
"""


def load(xml: str, ee: str = "tip", **kwargs) -> dqcontrol.RobotModel:
    return dqcontrol.RobotModel.from_urdf(xml, ee, **kwargs)


def test_every_error_derives_from_dqcontrol_error():
    for cls in (ConfigurationError, FrameError, ParameterError, URDFError):
        assert issubclass(cls, DQControlError)


def test_the_unbroken_urdf_loads():
    """The control case: every failure below comes from the one mutation."""
    model = load(make_urdf())
    assert model.nq == 1
    np.testing.assert_allclose(
        model.placement(np.array([np.pi / 2])).translation, [0.0, 0.3, 0.2], atol=1e-15
    )


# =========================================================================== URDF
def test_missing_file(tmp_path):
    path = tmp_path / "no_such_robot.urdf"
    with pytest.raises(URDFError, match="not found") as info:
        dqcontrol.RobotModel.from_urdf(path, "tip")
    assert str(path) in str(info.value)


def test_missing_file_given_as_str(tmp_path):
    path = str(tmp_path / "nothing_here.urdf")
    with pytest.raises(URDFError, match=re.escape(path)):
        dqcontrol.RobotModel.from_urdf(path, "tip")


def test_malformed_xml_truncated():
    xml = make_urdf()
    with pytest.raises(URDFError, match="malformed XML"):
        load(xml[: len(xml) // 2])


def test_malformed_xml_from_file_names_the_file(tmp_path):
    path = tmp_path / "broken.urdf"
    path.write_text(make_urdf()[:300])
    with pytest.raises(URDFError, match="malformed XML") as info:
        dqcontrol.RobotModel.from_urdf(path, "tip")
    assert str(path) in str(info.value)


def test_wrong_root_tag():
    with pytest.raises(URDFError, match="root element must be <robot>, got <model>"):
        load(make_urdf(root="model"))


def test_joint_with_unknown_parent_link():
    with pytest.raises(URDFError, match="parent link 'ghost' does not exist") as info:
        load(make_urdf(parent="ghost"))
    assert "joint1" in str(info.value)
    assert "'base'" in str(info.value)  # lists the links that exist


@pytest.mark.parametrize("xyz", ["0 nan 0.2", "0 0 inf", "0 0 -inf"])
def test_non_finite_origin(xyz):
    with pytest.raises(URDFError, match="must be finite") as info:
        load(make_urdf(origin_xyz=xyz))
    assert "joint1" in str(info.value)


def test_origin_with_wrong_count():
    with pytest.raises(URDFError, match="must hold 3 numbers"):
        load(make_urdf(origin_xyz="0 0"))


def test_negative_mass():
    with pytest.raises(URDFError, match="mass must be ≥ 0") as info:
        load(make_urdf(mass="-2.5"))
    assert "link1" in str(info.value) and "-2.5" in str(info.value)


def test_limit_lower_above_upper():
    with pytest.raises(URDFError, match=re.escape("lower=1.0 > upper=-1.0")) as info:
        load(make_urdf(lower="1.0", upper="-1.0"))
    assert "joint1" in str(info.value)


def test_multi_dof_joint_is_refused():
    with pytest.raises(URDFError, match="joints with more") as info:
        load(make_urdf(joint_type="floating"))
    assert "joint1" in str(info.value)


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


def test_unknown_locked_joint():
    with pytest.raises(FrameError, match="cannot lock unknown joint 'ghost_joint'") as info:
        dqcontrol.load_panda(locked_joints={"ghost_joint": 0.0})
    assert "panda_joint1" in str(info.value)


# =========================================================================== q
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


# =========================================================================== parameters
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


def test_bad_algebra_arguments():
    with pytest.raises(ParameterError, match="non-zero 3-vector"):
        qfrom_axis_angle([0.0, 0.0, 0.0], 1.0)
    with pytest.raises(ParameterError, match="non-zero 3-vector"):
        qfrom_axis_angle([1.0, 0.0], 1.0)
    with pytest.raises(ParameterError, match="no inverse"):
        dq_inv(np.array([0.0, 0, 0, 0, 1, 0, 0, 0]))
    with pytest.raises(ParameterError, match=re.escape("shape (8,)")):
        dq_to_se3(np.zeros(7))
    with pytest.raises(ParameterError, match=re.escape("shape (3, 3)")):
        qfrom_matrix(np.eye(4))
