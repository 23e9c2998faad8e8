"""Mesh files are checked when a URDF is loaded: each must exist, inside the package or URDF
folder it is looked up in; the error names the link, the file and the folders searched."""

from __future__ import annotations

import re

import pytest

from dqcontrol.errors import URDFError
from dqcontrol.model import RobotModel
from dqcontrol.model.meshes import find_mesh
from dqcontrol.sim.mjcf_builder import resolve_mesh_path

_URDF = """<robot name="r">
  <link name="base"/>
  <link name="forearm">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
      ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="{mesh}"/></geometry></visual>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="forearm"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
</robot>"""


def _write(folder, mesh: str):
    path = folder / "robot.urdf"
    path.write_text(_URDF.format(mesh=mesh))
    return path


@pytest.fixture
def layout(tmp_path):
    """``tmp/share/my_arm/meshes/forearm.stl``, ``tmp/robot/meshes/forearm.stl`` and a file
    outside both, ``tmp/secret.stl``."""
    share = tmp_path / "share"
    (share / "my_arm" / "meshes").mkdir(parents=True)
    (share / "my_arm" / "meshes" / "forearm.stl").write_text("solid s\nendsolid s\n")
    robot = tmp_path / "robot"
    (robot / "meshes").mkdir(parents=True)
    (robot / "meshes" / "forearm.stl").write_text("solid s\nendsolid s\n")
    (tmp_path / "secret.stl").write_text("solid s\nendsolid s\n")
    return tmp_path


def test_relative_mesh_in_the_urdf_folder_loads(layout):
    robot = RobotModel.from_urdf(_write(layout / "robot", "meshes/forearm.stl"), "forearm")
    assert robot.nq == 1


def test_package_mesh_found_in_a_package_dir(layout):
    urdf = _write(layout / "robot", "package://my_arm/meshes/forearm.stl")
    robot = RobotModel.from_urdf(urdf, "forearm", package_dirs=[layout / "share"])
    found = resolve_mesh_path("package://my_arm/meshes/forearm.stl", robot.source)
    assert found == (layout / "share" / "my_arm" / "meshes" / "forearm.stl").resolve()


def test_missing_relative_mesh_names_link_file_and_folder(layout):
    with pytest.raises(URDFError) as info:
        RobotModel.from_urdf(_write(layout / "robot", "meshes/elbow.stl"), "forearm")
    message = str(info.value)
    assert "link 'forearm'" in message and "meshes/elbow.stl" in message
    assert str(layout / "robot") in message and "not found" in message


def test_missing_package_mesh_lists_the_package_dirs(layout):
    urdf = _write(layout / "robot", "package://my_arm/meshes/elbow.stl")
    with pytest.raises(URDFError) as info:
        RobotModel.from_urdf(urdf, "forearm", package_dirs=[layout / "share"])
    message = str(info.value)
    assert "link 'forearm'" in message and "package://my_arm/meshes/elbow.stl" in message
    assert str(layout / "share") in message and "package_dirs" in message


@pytest.mark.parametrize(
    "mesh", ["package://my_arm/../../secret.stl", "package://my_arm/meshes/../../../secret.stl"]
)
def test_package_path_leaving_its_folder_is_refused(layout, mesh):
    urdf = _write(layout / "robot", mesh)
    with pytest.raises(URDFError, match="leaves the folder") as info:
        RobotModel.from_urdf(urdf, "forearm", package_dirs=[layout / "share"])
    assert "link 'forearm'" in str(info.value) and mesh in str(info.value)


def test_relative_path_leaving_the_urdf_folder_is_refused(layout):
    assert (layout / "secret.stl").is_file()  # it exists, and is still refused
    urdf = _write(layout / "robot", "../secret.stl")
    with pytest.raises(URDFError, match="leaves the folder") as info:
        RobotModel.from_urdf(urdf, "forearm")
    assert str(layout / "secret.stl") in str(info.value)
    assert find_mesh("../secret.stl", (), layout / "robot").path is None


def test_dot_dot_that_stays_inside_is_accepted(layout):
    urdf = _write(layout / "robot", "meshes/../meshes/forearm.stl")
    assert RobotModel.from_urdf(urdf, "forearm").nq == 1


def test_absolute_mesh_path_must_exist(layout):
    RobotModel.from_urdf(_write(layout / "robot", str(layout / "secret.stl")), "forearm")
    with pytest.raises(URDFError, match=re.escape(str(layout / "nothing.stl"))):
        RobotModel.from_urdf(_write(layout / "robot", str(layout / "nothing.stl")), "forearm")


def test_missing_package_dir_is_refused(layout):
    urdf = _write(layout / "robot", "meshes/forearm.stl")
    with pytest.raises(URDFError, match="package folder .*no_such_dir.* does not exist"):
        RobotModel.from_urdf(urdf, "forearm", package_dirs=[layout / "no_such_dir"])


def test_urdf_text_resolves_relative_meshes_in_the_package_dirs(layout):
    xml = _URDF.format(mesh="my_arm/meshes/forearm.stl")
    with pytest.raises(URDFError, match="my_arm/meshes/forearm.stl"):
        RobotModel.from_urdf(xml, "forearm")
    assert RobotModel.from_urdf(xml, "forearm", package_dirs=[layout / "share"]).nq == 1
