"""The one door to ROS 2 (dqcontrol/ros2/ros.py): the modules it hands over, and the
``[ros2]`` extra named when one of them does not import. Imports only: no rclpy context,
no DDS."""

from __future__ import annotations

import sys

import pytest

from dqcontrol.errors import MissingExtraError
from dqcontrol.extras import has_extra
from dqcontrol.ros2.ros import PURPOSE, require_ros


@pytest.mark.parametrize("module", ["rclpy", "nav_msgs", "diagnostic_msgs.msg"])
def test_a_missing_module_names_the_extra(monkeypatch, module):
    monkeypatch.setitem(sys.modules, module, None)  # an import of it fails
    with pytest.raises(MissingExtraError) as info:
        require_ros()
    message = str(info.value)
    assert message.startswith(f"{PURPOSE} needs {module.partition('.')[0]}, which comes with")
    assert "pip install 'dqcontrol[ros2]'" in message


@pytest.mark.skipif(not has_extra("ros2"), reason="needs the [ros2] extra")
def test_the_modules_the_nodes_use():
    import diagnostic_msgs.msg
    import rclpy

    ros = require_ros()
    assert ros.rclpy is rclpy and ros.diagnostic is diagnostic_msgs.msg
    for name, cls in (
        ("sensor", "JointState"), ("std", "Float64MultiArray"), ("std", "String"),
        ("std_srvs", "Trigger"), ("geometry", "Point"), ("nav", "Path"),
        ("visualization", "Marker"), ("diagnostic", "KeyValue"),
    ):  # fmt: skip
        assert hasattr(getattr(ros, name), cls), (name, cls)
    for sub in ("executors", "qos", "signals"):
        assert hasattr(ros.rclpy, sub), sub
