"""``dqcontrol.model.urdf_source``: the LBR4p's URDF fuzzed with hypothesis and a two-link arm
broken one way per test; every bad input ends in a dqcontrol error that names the problem."""

from __future__ import annotations

import os
import re
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import dqcontrol
from dqcontrol.controllers import (
    LocalController,
)
from dqcontrol.errors import (
    FrameError,
    ParameterError,
    URDFError,
)
from dqcontrol.model import LBR4P_Q0, lbr4p_urdf_path, urdf_source
from dqcontrol.sim import MujocoSimulation, run_kinematic
from dqcontrol.trajectories import Circle

EE = "lbr4p_flange"
LBR4P_XML = lbr4p_urdf_path().read_text(encoding="utf-8")
_ROOT = ET.fromstring(LBR4P_XML)
JOINTS = [j.get("name") for j in _ROOT.findall("joint")]
MOVING_JOINTS = [j.get("name") for j in _ROOT.findall("joint") if j.get("type") == "revolute"]
LINKS = [link.get("name") for link in _ROOT.findall("link")]
MASSIVE_LINKS = [link.get("name") for link in _ROOT.findall("link") if link.find("inertial")]
#: The document ends here; a cut before it cannot be well-formed.
CLOSE = LBR4P_XML.rindex("</robot>")

# how hypothesis spells a bad number in a URDF attribute
NON_FINITE = st.sampled_from(["nan", "NaN", "inf", "-inf", "Infinity", "1e999", "-1e999"])


def load(xml: str | bytes | os.PathLike) -> dqcontrol.RobotModel:
    return dqcontrol.RobotModel.from_urdf(xml, EE)


def tree() -> ET.Element:
    """A fresh, mutable copy of the LBR4p's document."""
    return ET.fromstring(LBR4P_XML)


def text(root: ET.Element) -> str:
    return ET.tostring(root, encoding="unicode")


def find(root: ET.Element, tag: str, name: str) -> ET.Element:
    elem = root.find(f"{tag}[@name='{name}']")
    assert elem is not None, (tag, name)
    return elem


def urdf_error(xml, *fragments: str) -> URDFError:
    """Loading ``xml`` raises a URDFError whose message holds every fragment."""
    with pytest.raises(URDFError) as info:
        load(xml)
    message = str(info.value)
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    return info.value


def test_the_unbroken_lbr4p_loads_and_round_trips():
    """The control case: every failure below comes from its one mutation (and the
    ElementTree round trip used to mutate it changes nothing)."""
    a, b = load(LBR4P_XML), load(text(tree()))
    np.testing.assert_allclose(a.pose(LBR4P_Q0), b.pose(LBR4P_Q0), atol=1e-15)
    assert a.nq == 7


# =========================================================================== XML
@given(cut=st.integers(1, CLOSE))
def test_truncated_text_is_malformed_xml(cut):
    urdf_error(LBR4P_XML[:cut], "malformed XML", "<string>")


@settings(max_examples=25)
@given(cut=st.integers(1, CLOSE))
def test_truncated_file_names_the_file(cut):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "lbr4p_cut.urdf"
        path.write_text(LBR4P_XML[:cut], encoding="utf-8")
        urdf_error(path, "malformed XML", str(path))


@pytest.mark.parametrize("xml", ["", "   \n\t", b""], ids=["empty", "blank", "empty-bytes"])
def test_empty_urdf(xml):
    urdf_error(xml, "the URDF is empty")


def test_urdf_as_bytes_is_read_as_text():
    assert load(LBR4P_XML.encode()).nq == 7


@pytest.mark.parametrize("value", [None, 42, 3.5, ["<robot/>"]], ids=repr)
def test_urdf_of_the_wrong_type(value):
    urdf_error(value, "urdf must be a path to a .urdf file or the XML text itself")


def test_a_folder_is_not_a_urdf(tmp_path):
    urdf_error(tmp_path, "URDF file not found", str(tmp_path))


def test_billion_laughs_is_refused():
    """Entity expansion (a few hundred bytes → gigabytes) is stopped by the parser."""
    lol = "".join(
        f'<!ENTITY lol{i} "{f"&lol{i - 1};" * 10}">' for i in range(1, 10)
    )  # fmt: skip
    xml = (
        f'<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY lol0 "lol">{lol}]>'
        '<robot name="&lol9;"><link name="a"/></robot>'
    )
    urdf_error(xml, "malformed XML", "amplification")


def test_external_entity_is_not_fetched():
    xml = (
        '<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY secret SYSTEM "file:///etc/passwd">]>'
        '<robot name="&secret;"><link name="a"/></robot>'
    )
    urdf_error(xml, "malformed XML", "external entity")


# =========================================================================== structure
@given(joint=st.sampled_from(JOINTS))
def test_missing_joint_leaves_two_roots(joint):
    root = tree()
    elem = find(root, "joint", joint)
    orphan = elem.find("child").get("link")
    root.remove(elem)
    urdf_error(text(root), "one tree with one root", orphan)


@given(link=st.sampled_from(LINKS))
def test_missing_link_is_named(link):
    root = tree()
    root.remove(find(root, "link", link))
    err = urdf_error(text(root), f"'{link}' does not exist")
    assert "joint '" in str(err)  # and the joint that refers to it


@given(link=st.sampled_from(LINKS))
def test_duplicate_link(link):
    root = tree()
    root.append(ET.fromstring(f'<link name="{link}"/>'))
    urdf_error(text(root), f"link '{link}' is defined twice")


@given(joint=st.sampled_from(MOVING_JOINTS))
def test_revolute_joint_without_limit(joint):
    root = tree()
    elem = find(root, "joint", joint)
    elem.remove(elem.find("limit"))
    urdf_error(text(root), f"joint '{joint}'", "needs <limit")


@given(joint=st.sampled_from(MOVING_JOINTS), kind=st.sampled_from(["spherical", "", "REVOLUTE"]))
def test_unknown_joint_type(joint, kind):
    root = tree()
    find(root, "joint", joint).set("type", kind)
    urdf_error(text(root), f"joint '{joint}'", f"type '{kind}' is not one of")


def test_a_cycle_has_no_root():
    root = tree()
    first = find(root, "joint", "lbr4p_pedestal_joint")
    loop = ET.fromstring(
        '<joint name="loop" type="fixed"><parent link="lbr4p_flange"/>'
        '<child link="base_link"/></joint>'
    )
    root.append(loop)
    assert first is not None
    urdf_error(text(root), "one tree with one root", "roots found: []")


def test_missing_end_effector_frame():
    root = tree()
    root.remove(find(root, "joint", "lbr4p_flange_joint"))
    root.remove(find(root, "link", "lbr4p_flange"))
    with pytest.raises(FrameError, match="unknown end-effector frame 'lbr4p_flange'"):
        load(text(root))


# =========================================================================== masses
@settings(max_examples=30)
@given(links=st.sets(st.sampled_from(MASSIVE_LINKS), min_size=1))
def test_zero_mass_is_accepted(links):
    """Massless links are legitimate (virtual frames such as the Panda's link8)."""
    root = tree()
    for name in links:
        find(root, "link", name).find("inertial/mass").set("value", "0")
    assert load(text(root)).nq == 7


@given(
    link=st.sampled_from(MASSIVE_LINKS),
    mass=st.floats(max_value=-1e-300, allow_nan=False, allow_infinity=False),
)
def test_negative_mass(link, mass):
    root = tree()
    find(root, "link", link).find("inertial/mass").set("value", repr(mass))
    urdf_error(text(root), f"link '{link}'", "mass must be ≥ 0 kg")


@given(link=st.sampled_from(MASSIVE_LINKS), value=NON_FINITE)
def test_non_finite_mass(link, value):
    root = tree()
    find(root, "link", link).find("inertial/mass").set("value", value)
    urdf_error(text(root), f"link '{link}'", "'value' must be finite")


@given(
    link=st.sampled_from(MASSIVE_LINKS),
    key=st.sampled_from(["ixx", "iyy", "izz"]),
    value=st.floats(max_value=-1e-300, allow_nan=False, allow_infinity=False),
)
def test_negative_inertia(link, key, value):
    root = tree()
    find(root, "link", link).find("inertial/inertia").set(key, repr(value))
    urdf_error(text(root), f"link '{link}'", f"inertia {key} must be ≥ 0")


def _massless_robot() -> str:
    """Every link without mass *and* without rotational inertia: ``M(q) = 0``."""
    xml = re.sub(r'<mass value="[^"]*"/>', '<mass value="0"/>', LBR4P_XML)
    return re.sub(r'i(xx|yy|zz|xy|xz|yz)="[^"]*"', r'i\1="0"', xml)


def test_massless_robot_loads_for_kinematics_but_not_for_dynamics():
    """Decision: a robot whose moving links have neither mass nor inertia is accepted at
    load — the controllers are kinematic and need neither — but every consumer of its
    dynamics must refuse it. MuJoCo does, naming the first massless moving body."""
    robot = load(_massless_robot())
    np.testing.assert_array_equal(robot.mass_matrix(LBR4P_Q0), np.zeros((7, 7)))
    res = run_kinematic(LocalController(robot, Circle(2.0), 0.05), LBR4P_Q0)
    assert res.metrics.completed
    with pytest.raises(URDFError, match="mass and inertia of moving bodies") as info:
        MujocoSimulation(robot)
    assert "lbr4p_link_1" in str(info.value)


def test_dynamics_aware_limits_refuse_a_singular_mass_matrix():
    robot = load(_massless_robot())
    with pytest.raises(ParameterError, match="M_jj"):
        robot.acceleration_limits(LBR4P_Q0)
    with pytest.raises(ParameterError, match="joint 'lbr4p_joint_1' moves no mass"):
        robot.fast.acceleration_limits_batch(np.tile(LBR4P_Q0, (3, 1)), 1.0, 0.5, 50.0)


# =========================================================================== numbers
_ORIGIN_OWNERS = [("joint", j) for j in JOINTS] + [("link", n) for n in MASSIVE_LINKS]


@given(
    owner=st.sampled_from(_ORIGIN_OWNERS),
    attribute=st.sampled_from(["xyz", "rpy"]),
    index=st.integers(0, 2),
    value=NON_FINITE,
)
def test_non_finite_origin(owner, attribute, index, value):
    tag, name = owner
    root = tree()
    elem = find(root, tag, name)
    origin = elem.find("origin") if tag == "joint" else elem.find("inertial/origin")
    numbers = (origin.get(attribute) or "0 0 0").split()
    numbers[index] = value
    origin.set(attribute, " ".join(numbers))
    urdf_error(text(root), f"{tag} '{name}'", "must be finite")


@given(
    joint=st.sampled_from(JOINTS),
    index=st.integers(0, 2),
    value=st.floats(min_value=1.0001e4, max_value=1e308) | st.floats(-1e308, -1.0001e4),
)
def test_absurd_origin(joint, index, value):
    """Finite but absurd offsets (|x| > 10 km) would overflow the kinematics."""
    root = tree()
    origin = find(root, "joint", joint).find("origin")
    numbers = origin.get("xyz").split()
    numbers[index] = repr(value)
    origin.set("xyz", " ".join(numbers))
    urdf_error(text(root), f"joint '{joint}'", "origin xyz must lie within ±10000 m")


@given(
    joint=st.sampled_from(MOVING_JOINTS),
    attribute=st.sampled_from(["lower", "upper", "effort", "velocity"]),
    value=NON_FINITE,
)
def test_non_finite_limit(joint, attribute, value):
    root = tree()
    find(root, "joint", joint).find("limit").set(attribute, value)
    urdf_error(text(root), f"joint '{joint}'", f"'{attribute}' must be finite")


@given(
    joint=st.sampled_from(MOVING_JOINTS),
    lower=st.floats(-10.0, 10.0),
    gap=st.floats(1e-9, 10.0),
)
def test_limits_min_above_max(joint, lower, gap):
    upper = lower - gap
    if not lower > upper:  # the gap vanished in rounding
        return
    root = tree()
    limit = find(root, "joint", joint).find("limit")
    limit.set("lower", repr(lower))
    limit.set("upper", repr(upper))
    urdf_error(text(root), f"joint '{joint}'", f"lower={lower} > upper={upper}", "lower ≤ upper")


@given(
    joint=st.sampled_from(MOVING_JOINTS),
    attribute=st.sampled_from(["effort", "velocity"]),
    value=st.floats(max_value=-1e-300, allow_nan=False, allow_infinity=False),
)
def test_negative_effort_or_velocity_limit(joint, attribute, value):
    root = tree()
    find(root, "joint", joint).find("limit").set(attribute, repr(value))
    urdf_error(text(root), f"joint '{joint}'", f"limit {attribute} must be ≥ 0")


@given(joint=st.sampled_from(MOVING_JOINTS))
def test_zero_axis(joint):
    root = tree()
    find(root, "joint", joint).find("axis").set("xyz", "0 0 0")
    urdf_error(text(root), f"joint '{joint}'", "axis must be non-zero")


# =========================================================================== size
def test_huge_text_is_refused_before_parsing():
    pad = "<!--" + "x" * (urdf_source.MAX_URDF_BYTES + 1) + "-->"
    xml = LBR4P_XML.replace("<robot ", pad + "<robot ", 1)
    urdf_error(xml, "refusing over", str(urdf_source.MAX_URDF_BYTES))


def test_huge_file_is_refused_before_reading(tmp_path):
    path = tmp_path / "huge.urdf"
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(LBR4P_XML.replace("</robot>", ""))
        fh.seek(urdf_source.MAX_URDF_BYTES + 10)  # a sparse file: no 20 MB written
        fh.write("</robot>")
    urdf_error(path, str(path), "refusing files over", str(urdf_source.MAX_URDF_BYTES))


# =========================================================================== anything
_MUTATION_VALUES = st.one_of(
    st.text(max_size=12),
    NON_FINITE,
    st.floats().map(repr),
    st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=4).map(lambda v: " ".join(map(repr, v))),
)


def _attributes(root: ET.Element) -> list[tuple[int, str]]:
    elems = list(root.iter())
    return [(i, key) for i, e in enumerate(elems) for key in sorted(e.attrib)]


_ATTRIBUTES = _attributes(_ROOT)


@settings(max_examples=150)
@given(
    target=st.sampled_from(_ATTRIBUTES),
    value=_MUTATION_VALUES,
    simulate=st.booleans(),
)
def test_any_attribute_mutation_loads_or_raises_a_dqcontrol_error(target, value, simulate):
    """Replace one attribute anywhere with junk: the robot loads (and simulates), or a
    dqcontrol error says why — no other exception escapes."""
    index, key = target
    root = tree()
    list(root.iter())[index].set(key, value)
    try:
        robot = load(text(root))
    except (URDFError, FrameError) as exc:
        assert str(exc)
        return
    q = np.clip(LBR4P_Q0, robot.limits.q_min, robot.limits.q_max) if robot.nq == 7 else None
    if q is not None:
        assert np.isfinite(robot.pose(q)).all()
    if simulate and q is not None:
        try:
            sim = MujocoSimulation(robot)
        except (URDFError, ParameterError) as exc:
            assert str(exc)
            return
        m = sim.reset(q)
        assert np.isfinite(m.q).all()


@settings(max_examples=60)
@given(index=st.integers(1, len(list(_ROOT.iter())) - 1))
def test_removing_any_element_loads_or_raises_a_dqcontrol_error(index):
    root = tree()
    elems = list(root.iter())
    parents = {child: parent for parent in root.iter() for child in parent}
    victim = elems[index]
    parents[victim].remove(victim)
    try:
        load(text(root))
    except (URDFError, FrameError) as exc:
        assert str(exc)


# =========================================================================== a two-link arm
# Each URDF error once on a small string: a two-link arm (``base`` → ``link1`` by the revolute
# ``joint1``) that loads, and one mutation of it per test.
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


def load_arm(xml: str, ee: str = "tip", **kwargs) -> dqcontrol.RobotModel:
    return dqcontrol.RobotModel.from_urdf(xml, ee, **kwargs)


def test_the_unbroken_urdf_loads():
    """The control case: every failure below comes from the one mutation."""
    model = load_arm(make_urdf())
    assert model.nq == 1
    np.testing.assert_allclose(
        model.placement(np.array([np.pi / 2])).translation, [0.0, 0.3, 0.2], atol=1e-15
    )


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
        load_arm(xml[: len(xml) // 2])


def test_malformed_xml_from_file_names_the_file(tmp_path):
    path = tmp_path / "broken.urdf"
    path.write_text(make_urdf()[:300])
    with pytest.raises(URDFError, match="malformed XML") as info:
        dqcontrol.RobotModel.from_urdf(path, "tip")
    assert str(path) in str(info.value)


def test_wrong_root_tag():
    with pytest.raises(URDFError, match="root element must be <robot>, got <model>"):
        load_arm(make_urdf(root="model"))


def test_joint_with_unknown_parent_link():
    with pytest.raises(URDFError, match="parent link 'ghost' does not exist") as info:
        load_arm(make_urdf(parent="ghost"))
    assert "joint1" in str(info.value)
    assert "'base'" in str(info.value)  # lists the links that exist


@pytest.mark.parametrize("xyz", ["0 nan 0.2", "0 0 inf", "0 0 -inf"])
def test_non_finite_origin_of_the_two_link_arm(xyz):
    with pytest.raises(URDFError, match="must be finite") as info:
        load_arm(make_urdf(origin_xyz=xyz))
    assert "joint1" in str(info.value)


def test_origin_with_wrong_count():
    with pytest.raises(URDFError, match="must hold 3 numbers"):
        load_arm(make_urdf(origin_xyz="0 0"))


def test_negative_mass_of_the_two_link_arm():
    with pytest.raises(URDFError, match="mass must be ≥ 0") as info:
        load_arm(make_urdf(mass="-2.5"))
    assert "link1" in str(info.value) and "-2.5" in str(info.value)


def test_limit_lower_above_upper():
    with pytest.raises(URDFError, match=re.escape("lower=1.0 > upper=-1.0")) as info:
        load_arm(make_urdf(lower="1.0", upper="-1.0"))
    assert "joint1" in str(info.value)


def test_multi_dof_joint_is_refused():
    with pytest.raises(URDFError, match="joints with more") as info:
        load_arm(make_urdf(joint_type="floating"))
    assert "joint1" in str(info.value)
