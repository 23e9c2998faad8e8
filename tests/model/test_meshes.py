"""Mesh files are checked when a URDF is loaded: each must exist (a ``package://`` path inside
its package folder, a relative path against the URDF's folder, wherever it lands) and be of a
format its element's readers read; the error names the link, the file and the folders
searched or the formats accepted."""

from __future__ import annotations

import re

import pytest

from dqcontrol.errors import URDFError
from dqcontrol.model import RobotModel
from dqcontrol.model.collision import _robot_geometry
from dqcontrol.model.meshes import COLLISION_FORMATS, VISUAL_FORMATS, find_mesh
from dqcontrol.sim.mjcf_builder import resolve_mesh_path
from dqcontrol.viz.meshcat_viewer import robot_visual_models

_URDF = """<robot name="r">
  <link name="base"/>
  <link name="forearm">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
      ixy="0" ixz="0" iyz="0"/></inertial>
    <{kind}><geometry><mesh filename="{mesh}"/></geometry></{kind}>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="forearm"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
</robot>"""


_FACETS = ((0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3))
_CORNERS = ((0, 0, 0), (0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1))
#: An ASCII STL tetrahedron (a valid mesh with a convex hull, for the geometry readers).
_STL = (
    "solid t\n"
    + "".join(
        "facet normal 0 0 0\nouter loop\n"
        + "".join("vertex {} {} {}\n".format(*_CORNERS[i]) for i in facet)
        + "endloop\nendfacet\n"
        for facet in _FACETS
    )
    + "endsolid t\n"
)


def _write(folder, mesh: str, kind: str = "visual"):
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "robot.urdf"
    path.write_text(_URDF.format(mesh=mesh, kind=kind))
    return path


@pytest.fixture
def layout(tmp_path):
    """``tmp/share/my_arm/meshes/forearm.stl``, ``tmp/robot/meshes/forearm.stl`` and a file
    outside both, ``tmp/secret.stl``."""
    share = tmp_path / "share"
    (share / "my_arm" / "meshes").mkdir(parents=True)
    (share / "my_arm" / "meshes" / "forearm.stl").write_text(_STL)
    robot = tmp_path / "robot"
    (robot / "meshes").mkdir(parents=True)
    (robot / "meshes" / "forearm.stl").write_text(_STL)
    (tmp_path / "secret.stl").write_text(_STL)
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
    "mesh",
    [
        "package://my_arm/../../secret.stl",
        "package://my_arm/meshes/../../../secret.stl",
        "package://../secret.stl",
        "package://../../../../etc/passwd",
    ],
)
def test_package_path_climbing_out_of_its_folder_is_refused(layout, mesh):
    urdf = _write(layout / "robot", mesh)
    with pytest.raises(URDFError, match="climbs out of its package folder") as info:
        RobotModel.from_urdf(urdf, "forearm", package_dirs=[layout / "share"])
    message = str(info.value)
    assert "link 'forearm'" in message and f"mesh '{mesh}'" in message
    assert f"Folders searched: ['{layout / 'share'}" in message
    assert find_mesh(mesh, (layout / "share",), layout / "robot").path is None


def test_relative_path_is_resolved_against_the_urdf_folder_wherever_it_lands(layout):
    """The usual layout of a description: ``robot/urdf/robot.urdf`` and ``robot/meshes/``;
    the viewer and the collision model read the very file found at load."""
    urdf = _write(layout / "robot" / "urdf", "../meshes/forearm.stl", kind="collision")
    robot = RobotModel.from_urdf(urdf, "forearm")
    found = str((layout / "robot" / "meshes" / "forearm.stl").resolve())
    assert f'filename="{found}"' in robot.source.xml_with_mesh_paths()
    assert [g.meshPath for g in _robot_geometry(robot).geometryObjects] == [found]
    outside = _write(layout / "robot" / "urdf", "../../secret.stl")
    _, visual = robot_visual_models(RobotModel.from_urdf(outside, "forearm"))
    assert [g.meshPath for g in visual.geometryObjects] == [str(layout / "secret.stl")]


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
    xml = _URDF.format(mesh="my_arm/meshes/forearm.stl", kind="visual")
    with pytest.raises(URDFError, match="my_arm/meshes/forearm.stl"):
        RobotModel.from_urdf(xml, "forearm")
    assert RobotModel.from_urdf(xml, "forearm", package_dirs=[layout / "share"]).nq == 1


def _mesh_file(layout, name: str) -> str:
    (layout / "robot" / "meshes" / name).write_text(_STL)
    return f"meshes/{name}"


@pytest.mark.parametrize(
    ("kind", "name"),
    [
        ("collision", "forearm.msh"),  # coal (collision model) has no .msh reader
        ("visual", "forearm.msh"),  # nor has the viewer
        ("visual", "forearm.txt"),
        ("collision", "forearm"),
    ],
)
def test_mesh_format_no_reader_of_its_element_reads_is_refused(layout, kind, name):
    urdf = _write(layout / "robot", _mesh_file(layout, name), kind)
    with pytest.raises(URDFError, match=f"accepted {kind} mesh formats") as info:
        RobotModel.from_urdf(urdf, "forearm")
    message = str(info.value)
    assert "link 'forearm'" in message and f"mesh 'meshes/{name}'" in message
    accepted = VISUAL_FORMATS if kind == "visual" else COLLISION_FORMATS
    assert str(sorted(accepted)) in message


@pytest.mark.parametrize(
    ("kind", "name"),
    [
        ("visual", "forearm.dae"),
        ("visual", "forearm.OBJ"),
        ("collision", "forearm.STL"),
        ("collision", "forearm.dae"),  # coal reads COLLADA; MuJoCo refuses it when built
    ],
)
def test_mesh_formats_every_reader_of_its_element_reads_load(layout, kind, name):
    urdf = _write(layout / "robot", _mesh_file(layout, name), kind)
    assert RobotModel.from_urdf(urdf, "forearm").nq == 1
