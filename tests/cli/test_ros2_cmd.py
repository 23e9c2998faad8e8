"""``dqcontrol ros2`` (dqcontrol/cli/ros2_cmd.py): its parser (the nodes, ``--ros-args``
passed through), the help without a node, and the one-line message when the ``[ros2]``
extra is missing. Nothing here starts rclpy (tests/ros2/test_nodes.py runs the nodes, in a
network namespace)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from dqcontrol.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[2]


_NO_ROS = textwrap.dedent(
    """
    import sys
    sys.modules["rclpy"] = None
    from dqcontrol.cli import main
    import dqcontrol.ros2  # the package imports without ROS 2
    sys.exit(main(sys.argv[1:]))
    """
)


@pytest.mark.parametrize("node", ["control", "sim"])
def test_without_the_extra_the_commands_say_so_in_one_line(node):
    proc = subprocess.run(
        [sys.executable, "-c", _NO_ROS, "ros2", node, "--ros-args", "-p", "period_s:=0.01"],
        capture_output=True, text=True, timeout=120, cwd=ROOT,
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "[ros2] extra: pip install 'dqcontrol[ros2]'" in lines[0]


def test_the_ros_args_are_passed_through_whole():
    args = build_parser().parse_args(
        ["ros2", "control", "--ros-args", "-p", "period_s:=0.01", "-r", "__ns:=/arm"]
    )
    assert args.node == "control"
    assert args.ros_args == ["-p", "period_s:=0.01", "-r", "__ns:=/arm"]
    assert build_parser().parse_args(["ros2", "sim"]).ros_args == []


def test_without_a_node_the_help_goes_to_stderr_with_exit_code_2(capsys):
    assert main(["ros2"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "usage: dqcontrol ros2" in err and "control" in err and "sim" in err


def test_a_missing_message_package_names_the_extra(monkeypatch):
    from dqcontrol import extras
    from dqcontrol.cli import ros2_cmd
    from dqcontrol.errors import MissingExtraError

    monkeypatch.setattr(extras, "available", lambda module: module != "nav_msgs")
    with pytest.raises(MissingExtraError) as info:
        ros2_cmd._check_extra()
    assert "needs nav_msgs" in str(info.value)
    assert "pip install 'dqcontrol[ros2]'" in str(info.value)
