"""A node's life in a process (dqcontrol/ros2/session.py), the parts that start no rclpy
context: the ``[ros2]`` extra checked before anything, and SIGTERM turned into
:class:`KeyboardInterrupt`. tests/ros2/test_nodes.py runs whole sessions, in a network
namespace."""

from __future__ import annotations

import signal
import sys

import pytest

from dqcontrol.errors import MissingExtraError
from dqcontrol.ros2 import ControlParams
from dqcontrol.ros2.session import _raise_interrupt, ros_node, spin_in_background


def test_without_rclpy_no_session_starts(monkeypatch):
    monkeypatch.setitem(sys.modules, "rclpy", None)
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(MissingExtraError, match=r"\[ros2\] extra"):
        with ros_node("dqcontrol_control", ["-p", "ee_frame:=f"], ControlParams):
            pytest.fail("the block ran without rclpy")
    assert signal.getsignal(signal.SIGTERM) is before  # no handler left behind
    with pytest.raises(MissingExtraError, match=r"\[ros2\] extra"):
        with spin_in_background(object()):
            pytest.fail("the block ran without rclpy")


def test_sigterm_becomes_a_keyboard_interrupt():
    with pytest.raises(KeyboardInterrupt):
        _raise_interrupt(signal.SIGTERM, None)
