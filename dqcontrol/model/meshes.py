"""Where a URDF's mesh files are, and whether they can be read, checked when the robot is
loaded.

A ``<mesh filename=...>`` is found as follows:

- ``package://pkg/rest`` in each folder ``d`` of ``package_dirs`` as ``d/pkg/rest`` or
  ``d/rest`` (``d`` being the package itself), then in the folders above the URDF file
  (``a/pkg/rest``, or ``a/rest`` when ``a`` is named ``pkg``). The package folder
  (``d/pkg``, ``d``, ``a/pkg`` or ``a``) is where the path must stay: a ``rest`` whose
  ``..`` climbs out of it, or a package name ``..``, ``.`` or empty, is refused, not
  followed. The check is on the written path (``..`` and ``.`` folded), so a package laid
  out with symbolic links stays usable.
- a relative path against the URDF file's folder (or, for a URDF given as text, against
  each of the ``package_dirs``), wherever it lands: ``../meshes/link1.stl`` next to a
  ``urdf/`` folder is the usual layout of a robot description.
- ``file://`` URIs and absolute paths as they are.

The file found must also be of a format that every consumer of its element reads:

- ``<visual>`` meshes are drawn by the viewer (Pinocchio loads them with coal, Meshcat
  draws ``.stl``, ``.obj`` and ``.dae`` files) and by MuJoCo when it can (the simulator
  drops a visual mesh it cannot read: it only matters for drawing), so
  :data:`VISUAL_FORMATS` are the viewer's.
- ``<collision>`` meshes are the collision model's convex hulls (coal reads ``.stl``,
  ``.obj`` and ``.dae``), so :data:`COLLISION_FORMATS` are coal's. MuJoCo's contact geometry
  reads ``.stl`` and ``.obj`` only: a robot with COLLADA collision meshes loads and runs in
  the kinematic loop and the viewer, and the MuJoCo model refuses it when it is built
  (:func:`~dqcontrol.sim.mjcf_builder.prepare_urdf_xml`, naming the link and the file; the
  commands check it before any run).

The format is judged by the file's extension (any case). :func:`absolute_mesh_xml` gives
the URDF with every mesh replaced by the file found here, so that the viewer, the collision
model and the simulator read exactly the files checked at load.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from dqcontrol.errors import URDFError

__all__ = [
    "COLLISION_FORMATS",
    "VISUAL_FORMATS",
    "MeshLookup",
    "absolute_mesh_xml",
    "check_meshes",
    "find_mesh",
]

#: Mesh formats accepted in a ``<visual>``: those the viewer draws (Meshcat via Pinocchio).
VISUAL_FORMATS = frozenset({".stl", ".obj", ".dae"})
#: Mesh formats accepted in a ``<collision>``: those the collision model (coal) reads.
COLLISION_FORMATS = frozenset({".stl", ".obj", ".dae"})

_FORMATS = {"visual": VISUAL_FORMATS, "collision": COLLISION_FORMATS}
_READERS = {
    "visual": "the viewer (Meshcat)",
    "collision": "the collision model (coal)",
}
_PACKAGE = "package://"
_FILE = "file://"


@dataclass(frozen=True)
class MeshLookup:
    """The result of looking up one mesh ``filename``.

    Attributes:
        filename: the URI or path written in the URDF.
        path: the file found (absolute), or ``None``.
        searched: the folders it was looked for in (empty for an absolute path).
        escaping: ``package://`` candidates refused because they leave their package folder.
    """

    filename: str
    path: Path | None
    searched: tuple[Path, ...]
    escaping: tuple[Path, ...] = ()


def _inside(folder: Path, relative: str) -> Path | None:
    """``folder/relative`` with ``..`` folded, or ``None`` if that leaves ``folder``."""
    base = os.path.normpath(os.path.abspath(folder))
    joined = os.path.normpath(os.path.join(base, relative))
    if os.path.commonpath([base, joined]) != base:
        return None
    return Path(joined)


def _joined(folder: Path, relative: str) -> Path:
    """``folder/relative`` made absolute, with ``..`` and ``.`` folded."""
    return Path(os.path.normpath(os.path.join(os.path.abspath(folder), relative)))


def _package_roots(package_dirs, directory) -> list[Path]:
    """Folders that may hold a package: the ``package_dirs``, then the URDF's folder and the
    folders above it."""
    roots = [Path(d) for d in package_dirs]
    if directory is not None:
        roots += [directory, *directory.parents]
    return roots


def _package_candidates(pkg: str, sub: str, package_dirs, directory) -> list[tuple[Path, str]]:
    """(package folder, path inside it) pairs for ``package://pkg/sub``, in search order: a
    folder ``r`` holds the package as ``r/pkg``, or is the package itself when it is one of
    the ``package_dirs`` or is named ``pkg``."""
    given = {Path(d) for d in package_dirs}
    pairs: list[tuple[Path, str]] = []
    for root in _package_roots(package_dirs, directory):
        pairs.append((root / pkg, sub))
        if root in given or root.name == pkg:
            pairs.append((root, sub))
    return pairs


def _find_package(filename: str, package_dirs, directory) -> MeshLookup:
    """Look up ``package://pkg/sub``: only inside each package folder."""
    rest = filename[len(_PACKAGE) :]
    pkg, _, sub = rest.partition("/")
    if pkg in ("", ".", ".."):  # the package folder itself would leave the folder searched
        roots = tuple(dict.fromkeys(_package_roots(package_dirs, directory)))
        return MeshLookup(filename, None, roots, tuple(_joined(r, rest) for r in roots))
    searched: list[Path] = []
    escaping: list[Path] = []
    for folder, relative in _package_candidates(pkg, sub, package_dirs, directory):
        searched.append(folder)
        candidate = _inside(folder, relative)
        if candidate is None:
            escaping.append(_joined(folder, relative))
        elif candidate.is_file():
            return MeshLookup(filename, candidate.resolve(), tuple(searched), tuple(escaping))
    return MeshLookup(filename, None, tuple(dict.fromkeys(searched)), tuple(escaping))


def _find_relative(filename: str, relative: str, folders: list[Path]) -> MeshLookup:
    """Look up a relative path against each of ``folders``, wherever it lands."""
    for folder in folders:
        candidate = _joined(folder, relative)
        if candidate.is_file():
            return MeshLookup(filename, candidate.resolve(), tuple(folders))
    return MeshLookup(filename, None, tuple(folders))


def find_mesh(filename: str, package_dirs: tuple[Path, ...], directory: Path | None) -> MeshLookup:
    """Look up a mesh ``filename`` (module docstring); ``directory`` is the URDF's folder."""
    if filename.startswith(_PACKAGE):
        return _find_package(filename, package_dirs, directory)
    raw = filename[len(_FILE) :] if filename.startswith(_FILE) else filename
    if Path(raw).is_absolute():
        path = Path(raw)
        return MeshLookup(filename, path.resolve() if path.is_file() else None, ())
    folders = [directory] if directory is not None else list(package_dirs)
    return _find_relative(filename, raw, [Path(f) for f in folders])


def _link_meshes(root: ET.Element):
    """(link name, ``"visual"`` or ``"collision"``, ``<mesh>`` element) of every link."""
    for link in root.findall("link"):
        for kind in ("visual", "collision"):
            for element in link.findall(kind):
                for mesh in element.iter("mesh"):
                    yield link.get("name"), kind, mesh


def check_meshes(
    root: ET.Element, package_dirs: tuple[Path, ...], directory: Path | None, where: str
) -> None:
    """Raise :class:`URDFError` unless every visual and collision ``<mesh>`` of every link is
    found and of a format its consumers read (module docstring). The message names the link,
    the file, and the folders searched or the formats accepted."""
    for link, kind, mesh in _link_meshes(root):
        lookup = find_mesh(mesh.get("filename", ""), package_dirs, directory)
        if lookup.path is None:
            raise URDFError(_missing_mesh_message(f"{where}: link '{link}'", lookup))
        if lookup.path.suffix.lower() not in _FORMATS[kind]:
            raise URDFError(_format_message(f"{where}: link '{link}'", kind, lookup))


def absolute_mesh_xml(root: ET.Element, package_dirs, directory) -> str:
    """The URDF ``root`` as text, with the filename of every visual and collision mesh found
    by :func:`find_mesh` replaced by its absolute path (a mesh not found is left as written).
    ``root`` itself is not changed."""
    copy = ET.fromstring(ET.tostring(root, encoding="unicode"))
    for _, _, mesh in _link_meshes(copy):
        path = find_mesh(mesh.get("filename", ""), package_dirs, directory).path
        if path is not None:
            mesh.set("filename", str(path))
    return ET.tostring(copy, encoding="unicode")


def _format_message(head: str, kind: str, lookup: MeshLookup) -> str:
    suffix = (lookup.path.suffix if lookup.path is not None else "") or "no extension"
    return (
        f"{head}: {kind} mesh '{lookup.filename}' ({lookup.path}) has format '{suffix}', which "
        f"{_READERS[kind]} cannot read; accepted {kind} mesh formats: "
        f"{sorted(_FORMATS[kind])}. Convert the mesh, e.g. to STL."
    )


def _missing_mesh_message(head: str, lookup: MeshLookup) -> str:
    head = f"{head}: mesh '{lookup.filename}'"
    if not lookup.filename:
        return f"{head}: <mesh> has no filename"
    folders = [str(f) for f in lookup.searched]
    if lookup.escaping:
        return (
            f"{head} climbs out of its package folder (it would read {lookup.escaping[0]}); "
            f"a package:// path must stay inside its package. Folders searched: {folders}"
        )
    if not lookup.searched:
        return f"{head}: file not found (an absolute path)"
    hint = (
        "pass the folder that holds the package with package_dirs (--package-dir on the "
        "command line)"
        if lookup.filename.startswith(_PACKAGE)
        else "relative paths are resolved against the URDF's folder"
    )
    return f"{head}: file not found in the folders searched {folders}; {hint}"
