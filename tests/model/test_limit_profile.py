"""Robot limit profiles: the shipped files, the refusals, the profile on the robot model and
the bounds the controllers take from it."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from dqcontrol.controllers import LocalController, PathFollowingController
from dqcontrol.controllers.proportional import ProportionalController
from dqcontrol.model.limit_profile import ProfileError, load_profile, profile_names
from dqcontrol.trajectories import Circle

SHIPPED = (
    "franka_fr3",
    "franka_panda",
    "kuka_iiwa14_r820",
    "kuka_iiwa7_r800",
    "ur10e",
    "ur5e",
    "urdf",
)

#: Panda's position ranges [rad], rounded inwards.
RANGES = {
    1: (-2.8, 2.8),
    2: (-1.7, 1.7),
    3: (-2.8, 2.8),
    4: (-3.0, -0.1),
    5: (-2.8, 2.8),
    6: (0.0, 3.7),
    7: (-2.8, 2.8),
}
PANDA_JOINT = """
[[joint]]
name = "panda_joint{k}"
position_rad = [{lo}, {hi}]
velocity_rad_s = 2.0
acceleration_rad_s2 = 5.0
jerk_rad_s3 = "unbounded"
"""


def _write(tmp_path: Path, joints: str, head: str = "") -> str:
    text = head or 'source = "a test"\ncontrol_periods_s = [0.001]\n'
    path = tmp_path / "mine.toml"
    path.write_text(text + joints, encoding="utf-8")
    return str(path)


def _panda_file(tmp_path: Path, **replace: str) -> str:
    joints = "".join(PANDA_JOINT.format(k=k, lo=RANGES[k][0], hi=RANGES[k][1]) for k in range(1, 8))
    for old, new in replace.items():
        joints = joints.replace(old, new, 1)
    return _write(tmp_path, joints)


def test_the_shipped_profiles_are_listed_and_each_cites_its_source():
    assert tuple(profile_names()) == SHIPPED
    for name in SHIPPED:
        profile = load_profile(name)
        assert profile.name == name and len(profile.source) > 10
        n = len(profile.joint_names)
        assert n == (0 if name == "urdf" else 6 if name.startswith("ur") else 7)
        for arr in (profile.q_min, profile.q_max, profile.qd_max, profile.qdd_max):
            assert arr.shape == (n,)
        assert np.all(profile.q_min < profile.q_max) and np.all(profile.qd_max > 0)


def test_the_figures_are_the_vendors():
    panda = load_profile("franka_panda")
    np.testing.assert_array_equal(panda.qd_max, [2.175] * 4 + [2.61] * 3)
    np.testing.assert_array_equal(panda.qdd_max, [15, 7.5, 10, 12.5, 15, 20, 20])
    np.testing.assert_array_equal(panda.qddd_max, [7500, 3750, 5000, 6250, 7500, 10000, 10000])
    assert panda.q_min[3] == -3.0718 and panda.q_max[5] == 3.7525 and panda.periods_s == (0.001,)
    fr3 = load_profile("franka_fr3")
    np.testing.assert_array_equal(fr3.qd_max, [2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26])
    assert fr3.q_min[5] == 0.5445 and np.all(fr3.qddd_max == 5000)
    iiwa7, iiwa14 = load_profile("kuka_iiwa7_r800"), load_profile("kuka_iiwa14_r820")
    np.testing.assert_allclose(np.degrees(iiwa7.qd_max), [98, 98, 100, 130, 140, 180, 180])
    np.testing.assert_allclose(np.degrees(iiwa14.qd_max), [85, 85, 100, 75, 130, 135, 135])
    np.testing.assert_allclose(np.degrees(iiwa14.q_max), [170, 120, 170, 120, 170, 120, 175])
    assert np.all(np.isinf(iiwa7.qdd_max)) and iiwa7.periods_s[-1] == 0.005
    ur10e = load_profile("ur10e")
    np.testing.assert_allclose(np.degrees(ur10e.qd_max), [120, 120, 180, 180, 180, 180])
    np.testing.assert_allclose(ur10e.q_max, [2 * math.pi] * 2 + [math.pi] + [2 * math.pi] * 3)
    assert ur10e.joint_names[0] == "shoulder_pan_joint" and ur10e.periods_s == (0.002,)


def test_the_profile_on_the_robot_model(panda):
    robot = panda.with_limits("franka_panda")
    assert robot is not panda and robot.limit_profile == "franka_panda"
    assert panda.limit_profile == "urdf" and np.all(np.isinf(panda.limits.qdd_max))
    np.testing.assert_array_equal(robot.limits.qddd_max, load_profile("franka_panda").qddd_max)
    np.testing.assert_array_equal(robot.limits.effort_max, panda.limits.effort_max)
    q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    # the dynamics-aware bound: capped by the profile's acceleration, unchanged below it
    np.testing.assert_array_equal(
        robot.acceleration_limits(q), np.minimum(panda.acceleration_limits(q), robot.limits.qdd_max)
    )
    urdf = panda.with_limits("urdf")
    for name in ("q_min", "q_max", "qd_max"):
        np.testing.assert_array_equal(getattr(urdf.limits, name), getattr(panda.limits, name))


def test_controllers_take_the_profiles_bounds_unless_given(panda):
    robot = panda.with_limits("franka_panda")
    qdd = robot.limits.qdd_max
    local = LocalController(robot, Circle(1.0), 0.001)
    np.testing.assert_array_equal(local.qd_max, robot.limits.qd_max)
    np.testing.assert_array_equal(local.a_const, qdd)
    assert np.all(LocalController(panda, Circle(1.0), 0.001).a_const == 10.0)
    assert np.all(LocalController(robot, Circle(1.0), 0.001, acceleration_limit=3.0).a_const == 3)
    np.testing.assert_array_equal(ProportionalController(robot, Circle(1.0), 0.001).a_max, qdd)
    pf = PathFollowingController(robot, Circle(1.0), 0.001)
    assert pf.dynamic_acceleration and np.all(pf.qd_max == robot.limits.qd_max)


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda tmp: "nope", ["unknown limit profile 'nope'", "franka_panda", "ur10e"]),
        (lambda tmp: str(tmp / "absent.toml"), ["does not exist"]),
        (
            lambda tmp: _panda_file(tmp, **{"velocity_rad_s = 2.0\n": ""}),
            ["panda_joint1", "'velocity_rad_s'", "missing"],
        ),
        (
            lambda tmp: _panda_file(
                tmp, **{"acceleration_rad_s2 = 5.0": "acceleration_rad_s2 = -5"}
            ),
            ["panda_joint1", "'acceleration_rad_s2'", "> 0", "-5"],
        ),
        (
            lambda tmp: _panda_file(tmp, **{"[-2.8, 2.8]": "[-2.8, 2.9]"}),
            ["looser than the URDF", "panda_joint1", "position max", "2.9", "2.8973"],
        ),
        (
            lambda tmp: _panda_file(tmp, **{"velocity_rad_s = 2.0": "velocity_rad_s = 2.5"}),
            ["looser than the URDF", "panda_joint1", "velocity 2.5", "2.175"],
        ),
        (
            lambda tmp: _panda_file(tmp, **{"panda_joint7": "elbow"}),
            ["is for the joints", "'elbow'", "this robot's joints", "'panda_joint7'"],
        ),
        (lambda tmp: "ur5e", ["is for the joints", "shoulder_pan_joint", "panda_joint1"]),
    ],
)
def test_a_bad_profile_is_refused_with_one_clear_error(panda, tmp_path, make, words):
    with pytest.raises(ProfileError) as info:
        panda.with_limits(make(tmp_path))
    for word in words:
        assert word in str(info.value), (word, str(info.value))


def test_a_profile_in_another_joint_order_is_matched_by_name(panda, tmp_path):
    joints = "".join(
        PANDA_JOINT.format(k=k, lo=RANGES[k][0], hi=RANGES[k][1]) for k in (7, 6, 5, 4, 3, 2, 1)
    )
    joints = joints.replace("velocity_rad_s = 2.0", "velocity_rad_s = 1.0", 1)  # joint 7's
    robot = panda.with_limits(_write(tmp_path, joints))
    assert robot.limits.qd_max[6] == 1.0 and np.all(robot.limits.qd_max[:6] == 2.0)


@pytest.mark.parametrize(("spec", "name"), [("erd:ur5", "ur5e"), ("erd:ur10", "ur10e")])
def test_the_ur_profiles_fit_the_ur_arms_of_example_robot_data(spec, name):
    from dqcontrol.cli.robot_options import RobotRequest, load_robot

    robot, _, _ = load_robot(RobotRequest(spec, ee_frame="tool0", limits=name))
    profile = load_profile(name)
    np.testing.assert_array_equal(robot.limits.qd_max, profile.qd_max)
    assert robot.limits.q_max[2] == pytest.approx(math.pi) and robot.limit_profile == name


def test_profiles_compare_by_their_figures():
    panda = load_profile("franka_panda")
    assert panda == load_profile("franka_panda")
    assert panda != load_profile("kuka_iiwa7_r800")
    assert panda != dataclasses.replace(panda, qd_max=panda.qd_max * 0.5)
