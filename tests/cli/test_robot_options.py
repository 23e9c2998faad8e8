"""The robot of a command line (dqcontrol/cli/robot_options.py): ``--robot erd:NAME``,
``--lock``, ``--package-dir``, ``--tool``, a URDF with a continuous joint, the option types,
the robot rebuilt from a saved run's meta, and bad input → a message naming what is wrong,
exit code 2."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pytest
from cli.test_run_cmd import _bad

from dqcontrol.cli import main
from dqcontrol.cli.robot_options import (
    RobotRequest,
    add_robot_options,
    load_robot,
    parse_lock,
    parse_package_dir,
    parse_tool,
    robot_from_meta,
    robot_label,
)
from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0, lbr4p_urdf_path, load_panda
from dqcontrol.runs.storage import load_run


@pytest.fixture
def no_figures(monkeypatch):
    """Runs without figures and replays (tested in test_run_cmd.py): the controllers and the
    saved runs are what these tests check."""
    import dqcontrol.viz.figures as figures
    import dqcontrol.viz.meshcat_viewer as viewer

    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    monkeypatch.setattr(figures, "plot_comparison", lambda logs, path, **k: path)
    monkeypatch.setattr(viewer, "export_replay_html", lambda *a, path_points, **k: a[2])


# ---------------------------------------------------------------------- any arm
def test_run_an_example_robot_data_arm(tmp_path, capsys, no_figures):
    code = main(
        ["run", "--robot", "erd:ur5", "--ee-frame", "tool0", "--q0=0,-1.2,1.5,-1.9,-1.57,0",
         "--simulator", "kinematic", "--short", "--controllers", "pf", "--duration", "1",
         "--out", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    assert "ur5 on the circle" in capsys.readouterr().out
    log, record = load_run(tmp_path / "ur5_circle_T1s_kinematic" / "pf.npz")
    assert record["metrics"]["completed"] and log.q.shape[1] == 6
    assert log.meta["robot"] == "erd" and log.meta["erd"] == "ur5"
    assert robot_from_meta(log.meta).joint_names[0] == "shoulder_pan_joint"


def test_an_arm_with_collada_collision_meshes_runs_in_the_kinematic_loop(
    tmp_path, capsys, no_figures
):
    """example-robot-data's Kinova arm has COLLADA collision meshes: it loads and runs in
    the kinematic loop; MuJoCo, which cannot read them, is refused before any run."""
    argv = ["run", "--robot", "erd:kinova", "--ee-frame", "j2s6s200_end_effector",
            "--short", "--controllers", "local", "--duration", "1"]  # fmt: skip
    err = _bad([*argv, "--simulator", "mujoco", "--out", str(tmp_path / "mj")], capsys)
    assert "MuJoCo cannot read '.dae' meshes" in err and "--simulator kinematic" in err
    assert not (tmp_path / "mj").exists()
    code = main([*argv, "--simulator", "kinematic", "--out", str(tmp_path)])
    assert code in (0, 1)  # a run, whether or not this arm completes the circle
    log, _record = load_run(tmp_path / "kinova_circle_T1s_kinematic" / "local.npz")
    assert log.q.shape[1] == 6 and log.meta["erd"] == "kinova"


def test_erd_panda_with_locks_is_the_shipped_panda():
    locks = (("panda_finger_joint1", 0.0), ("panda_finger_joint2", 0.0))
    robot, q0, meta = load_robot(RobotRequest("erd:panda", "panda_hand_tcp", locks))
    panda = load_panda()
    assert robot.joint_names == panda.joint_names and meta["locked_joints"] == dict(locks)
    q = np.random.default_rng(11).uniform(-1.0, 1.0, size=7)
    np.testing.assert_allclose(robot.pose(q), panda.pose(q), rtol=0, atol=1e-12)


def test_lock_and_tool_shape_the_robot_and_survive_a_saved_run(tmp_path, capsys, no_figures):
    code = main(
        ["run", "--lock", "lbr4p_joint_7=0.3", "--tool", "0,0,0.1,0,0,0.5",
         "--simulator", "kinematic", "--short", "--controllers", "local", "--duration", "1",
         "--out", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    log, record = load_run(tmp_path / "lbr4p_circle_T1s_kinematic" / "local.npz")
    assert record["metrics"]["completed"] and log.q.shape[1] == 6
    assert log.meta["locked_joints"] == {"lbr4p_joint_7": 0.3}
    assert log.meta["tool"] == [0.0, 0.0, 0.1, 0.0, 0.0, 0.5]
    np.testing.assert_allclose(log.q[0], LBR4P_Q0[:6])  # the start posture, by joint name
    robot = robot_from_meta(log.meta)
    assert robot.ee_frame == "lbr4p_flange_tool" and robot.nq == 6
    # the tool: 0.1 m along the flange's z, turned by yaw 0.5 rad about it
    full = robot_from_meta({"robot": "lbr4p", "ee_frame": "lbr4p_flange"})
    flange = full.placement(np.r_[log.q[0], 0.3])
    tool = robot.placement(log.q[0])
    np.testing.assert_allclose(tool.translation, flange.act(np.array([0, 0, 0.1])), atol=1e-12)
    np.testing.assert_allclose(
        flange.rotation.T @ tool.rotation,
        [[np.cos(0.5), -np.sin(0.5), 0], [np.sin(0.5), np.cos(0.5), 0], [0, 0, 1]],
        atol=1e-12,
    )


def test_run_a_urdf_with_a_continuous_joint_and_meshes(tmp_path, capsys, no_figures):
    """A URDF in its own folder whose meshes live in a package found with --package-dir."""
    xml = lbr4p_urdf_path().read_text()
    xml = xml.replace('type="revolute"', 'type="continuous"', 1)
    mesh = '<visual><geometry><mesh filename="package://my_arm/base.stl"/></geometry></visual>'
    xml = xml.replace('<link name="lbr4p_link_0">', f'<link name="lbr4p_link_0">{mesh}', 1)
    assert mesh in xml
    (tmp_path / "share" / "my_arm").mkdir(parents=True)
    (tmp_path / "share" / "my_arm" / "base.stl").write_text("solid b\nendsolid b\n")
    urdf = tmp_path / "arm" / "my_arm.urdf"
    urdf.parent.mkdir()
    urdf.write_text(xml)
    q0 = "--q0=" + ",".join(str(v) for v in LBR4P_Q0)
    argv = [
        "run", "--robot", str(urdf), "--ee-frame", "lbr4p_flange", q0, "--simulator",
        "kinematic", "--short", "--controllers", "local", "--duration", "1", "--out", str(tmp_path),
    ]  # fmt: skip
    err = _bad(argv, capsys)  # without the package folder the mesh is not found
    assert "link 'lbr4p_link_0'" in err and "package://my_arm/base.stl" in err
    assert main([*argv, "--package-dir", str(tmp_path / "share")]) == 0
    log, _ = load_run(tmp_path / "my_arm_circle_T1s_kinematic" / "local.npz")
    assert log.meta["package_dirs"] == [str((tmp_path / "share").resolve())]
    assert robot_from_meta(log.meta).limits.q_max[0] == np.inf


@pytest.mark.parametrize(
    ("element", "messages"),
    [
        (
            '<visual><geometry><mesh filename="package://../../../../etc/passwd"/></geometry>'
            "</visual>",
            ["climbs out of its package folder", "Folders searched: ['"],
        ),
        (
            '<collision><geometry><mesh filename="meshes/base.dae"/></geometry></collision>',
            ["'meshes/base.dae'", "MuJoCo cannot read '.dae' meshes", "--simulator kinematic"],
        ),
    ],
)
def test_run_a_urdf_with_a_bad_mesh_stops_before_the_run(
    tmp_path, capsys, monkeypatch, element, messages
):
    """An escaping package path or a mesh format the simulator cannot read: exit code 2 with
    the link and the file named, and nothing run (no simulation started, no output folder)."""
    import dqcontrol.sim as sim

    def no_run(*args, **kwargs):
        raise AssertionError("a run started")

    monkeypatch.setattr(sim, "run_mujoco", no_run)
    monkeypatch.setattr(sim, "run_kinematic", no_run)
    xml = lbr4p_urdf_path().read_text()
    xml = xml.replace('<link name="lbr4p_link_0">', f'<link name="lbr4p_link_0">{element}', 1)
    assert element in xml
    (tmp_path / "arm" / "meshes").mkdir(parents=True)
    (tmp_path / "arm" / "meshes" / "base.dae").write_text("<COLLADA/>")
    urdf = tmp_path / "arm" / "my_arm.urdf"
    urdf.write_text(xml)
    out = tmp_path / "out"
    argv = [
        "run", "--robot", str(urdf), "--ee-frame", "lbr4p_flange", "--simulator", "mujoco",
        "--short", "--controllers", "local", "--duration", "1", "--out", str(out),
    ]  # fmt: skip
    err = _bad(argv, capsys)
    assert "link 'lbr4p_link_0'" in err and str(urdf) in err
    assert all(m in err for m in messages), err
    assert not out.exists()


# ---------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("argv", "messages"),
    [
        (["run", "--robot", "erd:no_such_arm"], ["no robot 'no_such_arm'", "ur5", "panda"]),
        (["run", "--robot", "erd:ur5"], ["--ee-frame is required", "tool0", "wrist_3_link"]),
        (["run", "--lock", "elbow=0"], ["--lock", "unknown joint 'elbow'", "lbr4p_joint_1"]),
        (["run", "--lock", "lbr4p_joint_7"], ["expected JOINT=VALUE", "'lbr4p_joint_7'"]),
        (["run", "--lock", "lbr4p_joint_7=x"], ["expected JOINT=VALUE"]),
        (["run", "--tool", "0,0"], ["expected 3 or 6", "X,Y,Z[,RX,RY,RZ]", "[m]", "[rad]"]),
        (["run", "--tool", "0,0,0.1,a,b,c"], ["expected 3 or 6"]),
        (["run", "--package-dir", "/no/such/folder"], ["'/no/such/folder' is not an existing"]),
        (["sim-server", "--lock", "elbow=0"], ["unknown joint 'elbow'", "lbr4p_joint_1"]),
        (["sim-server", "--tool", "1"], ["expected 3 or 6"]),
        (["sim-server", "--robot", "erd:nope"], ["no robot 'nope'", "ur5"]),
    ],
)
def test_bad_robot_options_exit_2_naming_the_problem(argv, messages, capsys):
    err = _bad(argv, capsys)
    for message in messages:
        assert message in err, (message, err)


# ---------------------------------------------------------------------- option types
def test_lock_is_a_joint_and_a_finite_value():
    assert parse_lock(" panda_finger_joint1 =0.01") == ("panda_finger_joint1", 0.01)
    assert parse_lock("j=-1e-3") == ("j", -0.001)
    for text in ("j", "=0", "j=", "j=nan", "j=inf", "j=x"):
        with pytest.raises(argparse.ArgumentTypeError, match="expected JOINT=VALUE"):
            parse_lock(text)


def test_tool_is_three_or_six_finite_numbers():
    assert parse_tool("0,0,0.1") == (0.0, 0.0, 0.1)
    assert parse_tool(" 1, 2, 3, 0.1, 0.2, 0.3") == (1.0, 2.0, 3.0, 0.1, 0.2, 0.3)
    for text in ("1,2", "1,2,3,4", "1,2,nan", "1,2,3,a,b,c", ""):
        with pytest.raises(argparse.ArgumentTypeError, match="expected 3 or 6"):
            parse_tool(text)


def test_package_dir_is_an_existing_folder_made_absolute(tmp_path, monkeypatch):
    (tmp_path / "share").mkdir()
    monkeypatch.chdir(tmp_path)
    assert parse_package_dir("share") == str((tmp_path / "share").resolve())
    (tmp_path / "file").write_text("")
    for text in ("file", "missing"):
        with pytest.raises(argparse.ArgumentTypeError, match="is not an existing folder"):
            parse_package_dir(text)


def test_the_options_make_the_request():
    parser = argparse.ArgumentParser()
    add_robot_options(parser)
    args = parser.parse_args(
        ["--robot", "erd:ur5", "--ee-frame", "tool0", "--lock", "a=1", "--lock", "b=2",
         "--tool", "0,0,0.1", "--limits", "ur5e"]
    )  # fmt: skip
    assert RobotRequest.from_args(args) == RobotRequest(
        "erd:ur5", "tool0", (("a", 1.0), ("b", 2.0)), (), (0.0, 0.0, 0.1), "ur5e"
    )
    assert RobotRequest.from_args(parser.parse_args([])) == RobotRequest()


# ---------------------------------------------------------------------- the saved run's meta
def test_a_request_survives_its_meta(tmp_path):
    request = RobotRequest(
        spec="erd:ur5", ee_frame="tool0", locked_joints=(("elbow_joint", 0.5),),
        package_dirs=(str(tmp_path),), tool=(0.0, 0.0, 0.1, 0.0, 0.0, 0.2),
        limits="limits.toml",
    )  # fmt: skip
    meta = request.to_meta({"robot": "erd", "erd": "ur5"}, "tool0")
    assert meta["limits"] == str((Path.cwd() / "limits.toml").resolve())
    again = RobotRequest.from_meta(meta)
    assert again == RobotRequest(**{**request.__dict__, "limits": meta["limits"]})
    urdf = RobotRequest.from_meta({"robot": "urdf", "urdf": "/a/arm.urdf", "ee_frame": "f"})
    assert urdf.spec == "/a/arm.urdf" and urdf.tool is None and urdf.locked_joints == ()
    assert RobotRequest().to_meta({"robot": "lbr4p"}, "lbr4p_flange") == {
        "robot": "lbr4p",
        "ee_frame": "lbr4p_flange",
    }


def test_a_meta_without_a_robot_is_refused():
    with pytest.raises(ValueError, match="does not name its robot"):
        RobotRequest.from_meta({"ee_frame": "f"})
    with pytest.raises(ParameterError, match="no 'robot' in its meta"):
        robot_from_meta({"trajectory": "circle"})
    with pytest.raises(ParameterError, match="cannot rebuild the robot of this run: --robot"):
        robot_from_meta({"robot": "urdf", "urdf": "/no/such/arm.urdf", "ee_frame": "f"})


def test_robot_label_names_the_arm():
    assert robot_label({"robot": "lbr4p"}) == "lbr4p"
    assert robot_label({"robot": "erd", "erd": "ur5"}) == "ur5"
    assert robot_label({"robot": "urdf", "urdf": "/x/my_arm.urdf"}) == "my_arm"


def test_the_start_posture_of_a_urdf_is_the_middle_of_its_limits(lbr4p):
    robot, q0, meta = load_robot(RobotRequest(str(lbr4p_urdf_path()), "lbr4p_flange"))
    lim = robot.limits
    np.testing.assert_allclose(q0, 0.5 * (lim.q_min + lim.q_max), atol=0)
    assert meta == {"robot": "urdf", "urdf": str(lbr4p_urdf_path().resolve()),
                    "ee_frame": "lbr4p_flange"}  # fmt: skip
    shipped, q_shipped, _ = load_robot(RobotRequest())
    np.testing.assert_array_equal(q_shipped, LBR4P_Q0)
    assert shipped.joint_names == lbr4p.joint_names


def test_the_cli_refuses_a_bad_profile_with_exit_code_2(tmp_path, capsys):
    for option in ("nope", str(tmp_path / "absent.toml"), "ur5e"):
        with pytest.raises(SystemExit) as info:
            main(["run", "--robot", "panda", "--limits", option, "--out", str(tmp_path)])
        assert info.value.code == 2
        assert "--limits" in capsys.readouterr().err
