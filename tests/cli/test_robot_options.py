"""The command line for any arm: ``--robot erd:NAME``, ``--lock``, ``--package-dir``,
``--tool``, a URDF with a continuous joint, the options every subcommand shares (``--out``,
``--no-progress``), and bad input → a message naming what is wrong, exit code 2."""

from __future__ import annotations

import re

import numpy as np
import pytest

from dqcontrol.cli import build_parser, main
from dqcontrol.cli.robot_options import RobotRequest, load_robot, robot_from_meta
from dqcontrol.model import LBR4P_Q0, lbr4p_urdf_path, load_panda
from dqcontrol.runs.storage import load_run

_SUBCOMMANDS = ("run", "table1", "faults", "view", "bench", "sim-server")


@pytest.fixture
def no_figures(monkeypatch):
    """Runs without figures and replays (tested in test_cli.py): the controllers and the
    saved runs are what these tests check."""
    import dqcontrol.viz.figures as figures
    import dqcontrol.viz.meshcat_viewer as viewer

    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    monkeypatch.setattr(figures, "plot_comparison", lambda logs, path, **k: path)
    monkeypatch.setattr(viewer, "export_replay_html", lambda *a, path_points, **k: a[2])


def _bad(argv: list[str], capsys) -> str:
    """Run ``argv``, expect exit code 2 and return stderr."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert re.search(rf"^dqcontrol {argv[0]}: error: ", err, re.MULTILINE), err
    assert "Traceback" not in err
    return err


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


def test_thesis_velocity_limits_need_all_seven_joints(capsys):
    err = _bad(["run", "--lock", "lbr4p_joint_7=0", "--velocity-limits", "thesis"], capsys)
    assert "this robot has 6 joints" in err


# ---------------------------------------------------------------------- shared options
def test_every_subcommand_takes_no_progress():
    parser = build_parser()
    minimal = {"view": ["RUN.npz"]}
    for name in _SUBCOMMANDS:
        args = parser.parse_args([name, *minimal.get(name, []), "--no-progress"])
        assert args.progress is False, name
        args = parser.parse_args([name, *minimal.get(name, [])])
        assert args.progress is True, name


def test_every_subcommand_that_writes_takes_out():
    parser = build_parser()
    minimal = {"view": ["RUN.npz"]}
    for name in ("run", "table1", "faults", "view", "bench"):
        args = parser.parse_args([name, *minimal.get(name, []), "--out", "somewhere"])
        assert args.out == "somewhere", name


def test_help_texts_speak_of_the_tool_only(capsys):
    """No project-history words (issue numbers, work rounds or stages) in any help text."""
    for name in _SUBCOMMANDS:
        with pytest.raises(SystemExit):
            main([name, "--help"])
        text = capsys.readouterr().out
        assert not re.search(r"\b(issue|round|stage)s?\b", text, re.IGNORECASE), name
        if name in ("run", "sim-server"):
            for option in ("--lock", "--package-dir", "--tool", "erd:NAME"):
                assert option in text, (name, option)
