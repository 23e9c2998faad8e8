"""The control node's robot (dqcontrol/ros2/robot_source.py): from a URDF file, or from the
``robot_description`` topic through a stand-in node that delivers (or not) the text; the
base frame against the URDF's root link; the description's QoS. No rclpy, no DDS."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.errors import DQControlError
from dqcontrol.model import lbr4p_urdf_path
from dqcontrol.ros2 import ControlParams
from dqcontrol.ros2.robot_source import base_frame, description_qos, load_control_robot

ROS = SimpleNamespace(
    std=SimpleNamespace(String="String"),
    rclpy=SimpleNamespace(
        qos=SimpleNamespace(
            QoSProfile=lambda **kw: SimpleNamespace(**kw),
            ReliabilityPolicy=SimpleNamespace(RELIABLE="reliable"),
            DurabilityPolicy=SimpleNamespace(TRANSIENT_LOCAL="transient local"),
        )
    ),
)


class _Node:
    """Delivers ``text`` (if any) to a ``robot_description`` subscription as it is made."""

    def __init__(self, text: str | None) -> None:
        self.text, self.subscribed, self.destroyed = text, [], []

    def create_subscription(self, kind, topic, callback, qos):
        self.subscribed.append((kind, topic, qos.durability))
        if self.text is not None:
            callback(SimpleNamespace(data=self.text))
        return "subscription"

    def destroy_subscription(self, sub):
        self.destroyed.append(sub)


def _root_link(urdf: str) -> str:
    root = ET.fromstring(urdf)
    children = {j.find("child").get("link") for j in root.findall("joint")}
    (link,) = [x.get("name") for x in root.findall("link") if x.get("name") not in children]
    return link


def test_the_description_is_reliable_and_kept_for_late_joiners():
    qos = description_qos(ROS)
    assert (qos.depth, qos.reliability, qos.durability) == (1, "reliable", "transient local")


def test_the_robot_from_a_file_has_its_frame_and_locks(lbr4p):
    params = ControlParams.from_values(
        {"ee_frame": "lbr4p_flange", "robot_description_file": str(lbr4p_urdf_path()),
         "locked_joints": ["lbr4p_joint_7=0.3"]}
    )  # fmt: skip
    robot = load_control_robot(None, None, params)  # a file needs no node
    assert robot.nq == 6 and robot.ee_frame == "lbr4p_flange"
    q = np.linspace(-0.5, 0.5, 6)
    np.testing.assert_allclose(robot.pose(q), lbr4p.pose(np.r_[q, 0.3]), atol=1e-12)
    assert base_frame(robot) == _root_link(lbr4p_urdf_path().read_text())


def test_the_robot_from_the_topic():
    text = lbr4p_urdf_path().read_text()
    node = _Node(text)
    params = ControlParams.from_values({"ee_frame": "lbr4p_flange", "wait_s": 0.01})
    robot = load_control_robot(node, ROS, params)
    assert robot.nq == 7 and base_frame(robot) == _root_link(text)
    assert node.subscribed == [("String", "/robot_description", "transient local")]
    assert node.destroyed == ["subscription"]  # the subscription is dropped once read


def test_no_description_in_time_says_what_to_do():
    node = _Node(None)
    params = ControlParams.from_values(
        {"ee_frame": "f", "wait_s": 0.01, "robot_description_topic": "/arm/description"}
    )
    with pytest.raises(DQControlError) as info:
        load_control_robot(node, ROS, params)
    assert str(info.value).startswith("no robot description on /arm/description in 0.01 s")
    assert "robot_description_file" in str(info.value)
    assert node.destroyed == ["subscription"]
