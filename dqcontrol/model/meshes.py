"""Where a URDF's mesh files are, checked when the robot is loaded.

A ``<mesh filename=...>`` is found as follows:

- ``package://pkg/rest`` in each folder ``d`` of ``package_dirs`` as ``d/pkg/rest`` or
  ``d/rest`` (``d`` being the package itself), then in the folders above the URDF file
  (``a/pkg/rest``, or ``a/rest`` when ``a`` is named ``pkg``);
- a relative path in the URDF's folder (or, for a URDF given as text, in the
  ``package_dirs``);
- ``file://`` URIs and absolute paths as they are.

A package or relative path must stay inside the folder it is looked up in: one whose ``..``
climbs out of it is refused, not followed. The check is on the written path (``..`` and
``.`` folded), so a package laid out with symbolic links stays usable.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from dqcontrol.errors import URDFError

__all__ = ["MeshLookup", "check_meshes", "find_mesh"]

_PACKAGE = "package://"
_FILE = "file://"


@dataclass(frozen=True)
class MeshLookup:
    """The result of looking up one mesh ``filename``.

    Attributes:
        filename: the URI or path written in the URDF.
        path: the file found (absolute), or ``None``.
        searched: the folders it was looked for in (empty for an absolute path).
        escaping: candidates refused because their ``..`` leaves the folder searched.
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


def _package_candidates(rest: str, package_dirs, directory) -> list[tuple[Path, str]]:
    """(folder, path inside it) pairs for ``package://rest``, in search order."""
    pkg, _, sub = rest.partition("/")
    pairs: list[tuple[Path, str]] = []
    for d in package_dirs:
        pairs += [(Path(d), rest), (Path(d), sub)]
    if directory is not None:
        for a in (directory, *directory.parents):
            pairs.append((a, rest))
            if a.name == pkg:
                pairs.append((a, sub))
    return pairs


def find_mesh(filename: str, package_dirs: tuple[Path, ...], directory: Path | None) -> MeshLookup:
    """Look up a mesh ``filename`` (module docstring); ``directory`` is the URDF's folder."""
    if filename.startswith(_PACKAGE):
        pairs = _package_candidates(filename[len(_PACKAGE) :], package_dirs, directory)
    else:
        raw = filename[len(_FILE) :] if filename.startswith(_FILE) else filename
        if Path(raw).is_absolute():
            path = Path(raw)
            return MeshLookup(filename, path.resolve() if path.is_file() else None, ())
        folders = [directory] if directory is not None else list(package_dirs)
        pairs = [(Path(f), raw) for f in folders]
    searched: list[Path] = []
    escaping: list[Path] = []
    for folder, relative in pairs:
        if folder not in searched:
            searched.append(folder)
        candidate = _inside(folder, relative)
        if candidate is None:
            escaping.append(Path(os.path.normpath(os.path.join(folder, relative))))
        elif candidate.is_file():
            return MeshLookup(filename, candidate.resolve(), tuple(searched), tuple(escaping))
    return MeshLookup(filename, None, tuple(searched), tuple(escaping))


def check_meshes(
    root: ET.Element, package_dirs: tuple[Path, ...], directory: Path | None, where: str
) -> None:
    """Raise :class:`URDFError` unless every ``<mesh>`` of every link is found (inside its
    folder). The message names the link, the file and the folders searched."""
    for link in root.findall("link"):
        for mesh in link.iter("mesh"):
            filename = mesh.get("filename", "")
            lookup = find_mesh(filename, package_dirs, directory)
            if lookup.path is not None:
                continue
            raise URDFError(_missing_mesh_message(link.get("name"), lookup, where))


def _missing_mesh_message(link: str | None, lookup: MeshLookup, where: str) -> str:
    head = f"{where}: link '{link}': mesh '{lookup.filename}'"
    if not lookup.filename:
        return f"{head}: <mesh> has no filename"
    folders = [str(f) for f in lookup.searched]
    if lookup.escaping:
        escaped = ", ".join(str(p) for p in lookup.escaping)
        return (
            f"{head} leaves the folder it is looked up in ({escaped}); paths must stay "
            f"inside the package or URDF folder. Folders searched: {folders}"
        )
    if not lookup.searched:
        return f"{head}: file not found (an absolute path)"
    hint = (
        "pass the folder that holds the package with package_dirs (--package-dir on the "
        "command line)"
        if lookup.filename.startswith(_PACKAGE)
        else "relative paths are resolved in the URDF's folder"
    )
    return f"{head}: file not found in the folders searched {folders}; {hint}"
