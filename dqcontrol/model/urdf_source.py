"""Reading and checking a URDF before Pinocchio sees it.

Pinocchio's parser (urdfdom) reports problems on stderr and raises a bare ``ValueError``;
this module reads the XML first, so that a user gets a :class:`~dqcontrol.errors.URDFError`
naming the element and the value that is wrong, and what would be right.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from dqcontrol.errors import URDFError
from dqcontrol.model.meshes import absolute_mesh_xml, check_meshes

#: A URDF larger than this is refused before parsing [bytes] (robot descriptions are kB).
MAX_URDF_BYTES = 20_000_000

_SUPPORTED_JOINTS = {"revolute", "prismatic", "fixed", "continuous", "floating", "planar"}

#: Largest accepted coordinate of an ``<origin xyz>`` [m]: beyond it the kinematics lose all
#: precision (and products of such lengths overflow), and no robot is that large.
MAX_ORIGIN_M = 1e4


@dataclass(frozen=True)
class URDFSource:
    """The text of a URDF and where it came from.

    Attributes:
        xml: the URDF document.
        path: the file it was read from, or ``None`` when given as a string.
        package_dirs: folders searched for ``package://`` mesh URIs.
    """

    xml: str
    path: Path | None
    package_dirs: tuple[Path, ...]

    @property
    def directory(self) -> Path | None:
        """Folder of the URDF file (relative mesh paths are resolved from it)."""
        return None if self.path is None else self.path.parent

    def xml_with_mesh_paths(self) -> str:
        """The URDF text with every visual and collision mesh as the absolute path of the
        file found (and checked) at load, so that every reader of the meshes (viewer,
        collision model, simulator) reads those very files
        (:func:`~dqcontrol.model.meshes.absolute_mesh_xml`)."""
        return absolute_mesh_xml(ET.fromstring(self.xml), self.package_dirs, self.directory)


def read_urdf(
    urdf: str | os.PathLike, package_dirs: Sequence[str | os.PathLike] | None = None
) -> URDFSource:
    """Read a URDF from a file path or an XML string, check it, and return its source.

    A string whose first non-blank character is ``<`` is taken as XML; anything else as a
    path. Raises :class:`URDFError` for a missing file, an oversize file, malformed XML,
    invalid values (see :func:`check_urdf_xml`), a package folder that does not exist, or a
    mesh file that cannot be found, climbs out of its package folder or has a format the
    viewer or simulator cannot read (:func:`~dqcontrol.model.meshes.check_meshes`).
    """
    dirs = tuple(Path(p).expanduser() for p in (package_dirs or []))
    for folder in dirs:
        if not folder.is_dir():
            raise URDFError(
                f"package folder '{folder}' does not exist (or is not a folder); package_dirs "
                "must name existing folders that hold the packages of package:// URIs"
            )
    if isinstance(urdf, bytes | bytearray):
        if len(urdf) > MAX_URDF_BYTES:
            raise URDFError(f"URDF text is {len(urdf)} bytes; refusing over {MAX_URDF_BYTES}")
        urdf = bytes(urdf).decode("utf-8", errors="replace")
    if not isinstance(urdf, str | os.PathLike):
        kind = type(urdf).__name__
        raise URDFError(f"urdf must be a path to a .urdf file or the XML text itself, got {kind}")
    if isinstance(urdf, str) and not urdf.strip():
        raise URDFError(
            "the URDF is empty: pass a path to a .urdf file or the XML text itself (a string "
            "starting with '<')"
        )
    if isinstance(urdf, str) and urdf.lstrip().startswith("<"):
        xml = urdf
        path = None
    else:
        path = Path(urdf)
        if not path.is_file():
            raise URDFError(
                f"URDF file not found: '{path}'. Pass an existing .urdf path or the XML text "
                "itself (a string starting with '<')."
            )
        size = path.stat().st_size
        if size > MAX_URDF_BYTES:
            raise URDFError(
                f"URDF file '{path}' is {size} bytes; refusing files over {MAX_URDF_BYTES} bytes"
            )
        try:
            xml = path.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            raise URDFError(f"cannot read URDF file '{path}': {exc.strerror or exc}") from None
    if len(xml) > MAX_URDF_BYTES:
        raise URDFError(f"URDF text is {len(xml)} characters; refusing over {MAX_URDF_BYTES}")
    where = str(path) if path else "<string>"
    check_urdf_xml(xml, where=where)
    check_meshes(ET.fromstring(xml), dirs, None if path is None else path.parent, where)
    return URDFSource(xml=xml, path=path, package_dirs=dirs)


def _floats(
    text: str | None, count: int, what: str, where: str, max_abs: float | None = None
) -> list[float]:
    if text is None:
        return [0.0] * count
    parts = text.split()
    if len(parts) != count:
        raise URDFError(f"{where}: {what} must hold {count} numbers, got '{text}'")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise URDFError(f"{where}: {what} must hold numbers, got '{text}'") from None
    if not all(math.isfinite(v) for v in values):
        raise URDFError(f"{where}: {what} must be finite, got '{text}'")
    if max_abs is not None and any(abs(v) > max_abs for v in values):
        raise URDFError(f"{where}: {what} must lie within ±{max_abs:g} m, got '{text}'")
    return values


def _float_attr(elem: ET.Element, name: str, where: str, default: float | None = None) -> float:
    text = elem.get(name)
    if text is None:
        if default is None:
            raise URDFError(f"{where}: attribute '{name}' is missing")
        return default
    try:
        value = float(text)
    except ValueError:
        raise URDFError(f"{where}: '{name}' must be a number, got '{text}'") from None
    if not math.isfinite(value):
        raise URDFError(f"{where}: '{name}' must be finite, got '{text}'")
    return value


def check_urdf_xml(xml: str, where: str = "<string>") -> None:
    """Check a URDF document for the errors Pinocchio would report badly or not at all.

    Checked: well-formed XML with a ``<robot>`` root; every link and joint named, unique;
    every joint's parent and child links exist; a single tree (one root); finite origins
    (positions within ±:data:`MAX_ORIGIN_M`) and axes; non-negative finite masses and finite
    inertia with positive diagonal; joint limits with ``lower ≤ upper`` and non-negative
    ``effort`` and ``velocity``.
    """
    root = _robot_root(xml, where)
    links = _check_links(root, where)
    children = _check_joints(root, links, where)
    roots = links - children
    if len(roots) != 1:
        raise URDFError(
            f"{where}: the links must form one tree with one root; roots found: {sorted(roots)}"
        )


def _robot_root(xml: str, where: str) -> ET.Element:
    """Parse the URDF text and return its ``<robot>`` element.

    Raises:
        URDFError: the XML is malformed or its root is not ``<robot>``.
    """
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as exc:
        raise URDFError(f"{where}: malformed XML ({exc})") from None
    if root.tag != "robot":
        raise URDFError(f"{where}: root element must be <robot>, got <{root.tag}>")
    return root


def _check_links(root: ET.Element, where: str) -> set[str]:
    """Check every ``<link>`` (named, unique, valid inertial) and return the link names.

    Raises:
        URDFError: a link has no name or a repeated one, its ``<inertial>`` is invalid
            (:func:`_check_inertial`), or the robot has no link at all.
    """
    links: set[str] = set()
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            raise URDFError(f"{where}: a <link> has no name")
        if name in links:
            raise URDFError(f"{where}: link '{name}' is defined twice")
        links.add(name)
        inertial = link.find("inertial")
        if inertial is not None:
            _check_inertial(inertial, f"{where}: link '{name}'")
    if not links:
        raise URDFError(f"{where}: the robot has no <link>")
    return links


def _check_inertial(inertial: ET.Element, lw: str) -> None:
    """Check a link's ``<inertial>``: a mass ≥ 0, a finite origin, an inertia diagonal ≥ 0.

    Args:
        inertial: the ``<inertial>`` element.
        lw: the link's place in the file, prefixed to every message.

    Raises:
        URDFError: the mass is missing or negative, the origin is not finite (or too far),
            or an inertia entry is not a finite number or a diagonal entry is negative.
    """
    mass = inertial.find("mass")
    if mass is None:
        raise URDFError(f"{lw}: <inertial> has no <mass>")
    m = _float_attr(mass, "value", lw + " mass")
    if m < 0.0:
        raise URDFError(f"{lw}: mass must be ≥ 0 kg, got {m}")
    origin = inertial.find("origin")
    if origin is not None:
        _floats(origin.get("xyz"), 3, "inertial origin xyz", lw, MAX_ORIGIN_M)
        _floats(origin.get("rpy"), 3, "inertial origin rpy", lw)
    inertia = inertial.find("inertia")
    if inertia is not None:
        for key in ("ixx", "iyy", "izz"):
            v = _float_attr(inertia, key, lw + " inertia", 0.0)
            if v < 0.0:
                raise URDFError(f"{lw}: inertia {key} must be ≥ 0 kg·m², got {v}")
        for key in ("ixy", "ixz", "iyz"):
            _float_attr(inertia, key, lw + " inertia", 0.0)


def _check_joints(root: ET.Element, links: set[str], where: str) -> set[str]:
    """Check every ``<joint>`` against the links and return the names of the child links.

    Raises:
        URDFError: a joint has no name or a repeated one, or is invalid
            (:func:`_check_joint`).
    """
    joints: set[str] = set()
    children: set[str] = set()
    for joint in root.findall("joint"):
        name = joint.get("name")
        if not name:
            raise URDFError(f"{where}: a <joint> has no name")
        if name in joints:
            raise URDFError(f"{where}: joint '{name}' is defined twice")
        joints.add(name)
        _check_joint(joint, links, children, f"{where}: joint '{name}'")
    return children


def _check_joint(joint: ET.Element, links: set[str], children: set[str], jw: str) -> None:
    """Check one joint's type, links, origin, axis and limits; add its child to ``children``.

    Args:
        joint: the ``<joint>`` element.
        links: the names of the robot's links.
        children: the links that are already a joint's child; updated in place.
        jw: the joint's place in the file, prefixed to every message.

    Raises:
        URDFError: the type is not supported, the parent or child link is missing or does
            not exist, the child already has a parent joint, the origin or axis is invalid,
            or the limits are (:func:`_check_limit`).
    """
    jtype = joint.get("type")
    if jtype not in _SUPPORTED_JOINTS:
        raise URDFError(f"{jw}: type '{jtype}' is not one of {sorted(_SUPPORTED_JOINTS)}")
    parent, child = joint.find("parent"), joint.find("child")
    if parent is None or child is None:
        raise URDFError(f"{jw}: needs both <parent link=...> and <child link=...>")
    for role, elem in (("parent", parent), ("child", child)):
        link_name = elem.get("link")
        if link_name not in links:
            raise URDFError(
                f"{jw}: {role} link '{link_name}' does not exist; links: {sorted(links)}"
            )
    if child.get("link") in children:
        raise URDFError(f"{jw}: link '{child.get('link')}' is the child of two joints")
    children.add(child.attrib["link"])  # present: checked above
    origin = joint.find("origin")
    if origin is not None:
        _floats(origin.get("xyz"), 3, "origin xyz", jw, MAX_ORIGIN_M)
        _floats(origin.get("rpy"), 3, "origin rpy", jw)
    axis = joint.find("axis")
    if axis is not None:
        a = _floats(axis.get("xyz"), 3, "axis xyz", jw)
        if jtype in ("revolute", "prismatic", "continuous") and not any(a):
            raise URDFError(f"{jw}: axis must be non-zero, got '{axis.get('xyz')}'")
    _check_limit(joint.find("limit"), jtype, jw)


def _check_limit(limit: ET.Element | None, jtype: str | None, jw: str) -> None:
    """Check a joint's ``<limit>``: present where required, ``lower ≤ upper``, rates ≥ 0.

    Args:
        limit: the joint's ``<limit>`` element, or ``None`` when it has none.
        jtype: the joint's type (revolute and prismatic joints need a limit).
        jw: the joint's place in the file, prefixed to every message.

    Raises:
        URDFError: a revolute or prismatic joint has no limit or ``lower > upper``, or a
            value is not a finite number, or ``effort`` or ``velocity`` is negative.
    """
    if jtype in ("revolute", "prismatic") and limit is None:
        raise URDFError(f"{jw}: a {jtype} joint needs <limit lower upper effort velocity>")
    if limit is None:
        return
    lower = _float_attr(limit, "lower", jw + " limit", 0.0)
    upper = _float_attr(limit, "upper", jw + " limit", 0.0)
    if jtype in ("revolute", "prismatic") and lower > upper:
        raise URDFError(f"{jw}: limit lower={lower} > upper={upper}; need lower ≤ upper [rad or m]")
    for key in ("effort", "velocity"):
        v = _float_attr(limit, key, jw + " limit", 0.0)
        if v < 0.0:
            raise URDFError(f"{jw}: limit {key} must be ≥ 0, got {v}")
