"""A concave collision mesh as convex parts, for MuJoCo's contacts (docs/theory.md §8.12).

MuJoCo collides every mesh as its convex hull. For a link whose mesh is concave (a hollow
housing, an elbow's recess) the hull fills space the link does not occupy, and two links
whose meshes are centimetres apart can touch as hulls: the simulated arm then pushes
against itself where the real one moves freely. A collision mesh whose hull exceeds its
own volume by more than :data:`HULL_EXCESS` is therefore split into convex parts
(approximate convex decomposition, CoACD, with the fixed :data:`COACD_SETTINGS` and seed):
each part is the hull of a piece of the mesh, so together they cover the mesh (to a few
hundredths of a millimetre: CoACD samples the surface), lie inside its hull, and hold
little space the mesh does not.

A decomposition takes about a second a mesh; the parts are kept on disk
(:func:`cache_dir`), keyed by the mesh file's bytes, its scale and the settings, so a robot
is decomposed once per machine. A mesh close enough to convex is left as it is (``None``),
so its simulation is exactly what it was.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from dqcontrol.extras import lazy_module

coacd = lazy_module("coacd", extra="sim", purpose="the convex parts of a concave mesh")

__all__ = [
    "COACD_SETTINGS",
    "HULL_EXCESS",
    "cache_dir",
    "convex_parts",
    "hull_excess",
    "mesh_arrays",
]

#: A mesh is split where its hull's volume exceeds the mesh's by more than this share.
HULL_EXCESS = 0.05
#: CoACD's settings: its concavity threshold, at most 32 parts, the mesh as it is (no
#: remeshing), a coarse search: about a second a mesh.
COACD_SETTINGS: dict[str, object] = {
    "threshold": 0.05,
    "max_convex_hull": 16,
    "preprocess_mode": "off",
    "resolution": 300,
    "mcts_iterations": 20,
    "mcts_max_depth": 1,
    "mcts_nodes": 8,
    "seed": 0,
}
#: The environment variable naming the folder the parts are kept in.
CACHE_ENV = "DQCONTROL_CACHE_DIR"


def cache_dir() -> Path:
    """Where the parts are kept: ``$DQCONTROL_CACHE_DIR``, else ``$XDG_CACHE_HOME/dqcontrol``,
    else ``~/.cache/dqcontrol``."""
    named = os.environ.get(CACHE_ENV)
    if named:
        return Path(named)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "dqcontrol"


def mesh_arrays(path: Path, scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The vertices ``(V, 3)`` [m, scaled] and triangles ``(F, 3)`` of a mesh file (read by
    coal, as the collision model reads it)."""
    import coal

    mesh = coal.MeshLoader().load(str(path), np.asarray(scale, dtype=float))
    vertices = np.array(mesh.vertices(), dtype=float).reshape(-1, 3)
    triangles = np.empty((mesh.num_tris, 3), dtype=np.int64)
    for i in range(mesh.num_tris):
        tri = mesh.tri_indices(i)
        triangles[i] = (tri[0], tri[1], tri[2])
    return vertices, triangles


def hull_excess(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """How much larger the hull's volume is than the mesh's, as a share of the mesh's
    (``inf`` for a mesh that encloses no volume: an open or flat one)."""
    from scipy.spatial import ConvexHull, QhullError

    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    volume = abs(float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum())) / 6.0
    try:
        hull = ConvexHull(vertices).volume
    except QhullError:  # flat or degenerate: nothing a hull could add
        return 0.0
    if volume <= 1e-3 * hull:
        return float("inf")
    return hull / volume - 1.0


def convex_parts(path: Path, scale: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """The vertices of the convex parts of the mesh at ``path`` (scaled by ``scale``), or
    ``None`` where its hull is within :data:`HULL_EXCESS` of it (module docstring)."""
    scale = np.asarray(scale, dtype=float)
    key = _key(path, scale)
    cached = _read(key)
    if cached is not None:
        return cached or None
    vertices, triangles = mesh_arrays(path, scale)
    if hull_excess(vertices, triangles) <= HULL_EXCESS:
        parts: tuple[np.ndarray, ...] = ()
    else:
        coacd.set_log_level("error")
        found = coacd.run_coacd(coacd.Mesh(vertices, triangles), **COACD_SETTINGS)
        parts = tuple(np.asarray(v, dtype=float).reshape(-1, 3) for v, _ in found)
    _write(key, parts)
    return parts or None


def _key(path: Path, scale: np.ndarray) -> str:
    """The cache key: the mesh file's bytes, the scale, the settings, CoACD's version."""
    digest = hashlib.sha256(Path(path).read_bytes())
    digest.update(np.ascontiguousarray(scale, dtype=float).tobytes())
    digest.update(json.dumps([COACD_SETTINGS, HULL_EXCESS], sort_keys=True).encode())
    digest.update(_coacd_version().encode())
    return digest.hexdigest()


def _coacd_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("coacd")
    except PackageNotFoundError:
        return "absent"


def _file(key: str) -> Path:
    return cache_dir() / "convex_parts" / f"{key}.npz"


def _read(key: str) -> tuple[np.ndarray, ...] | None:
    """The parts kept under ``key`` (``()``: the mesh is left whole), or ``None``."""
    try:
        with np.load(_file(key)) as data:
            return tuple(data[f"part{k}"] for k in range(int(data["count"])))
    except (OSError, KeyError, ValueError):
        return None


def _write(key: str, parts: tuple[np.ndarray, ...]) -> None:
    """Keep ``parts`` under ``key`` (written whole, then renamed: a reader never sees half
    a file); a cache that cannot be written is skipped."""
    target = _file(key)
    arrays: dict[str, np.ndarray] = {f"part{k}": p for k, p in enumerate(parts)}
    arrays["count"] = np.array(len(parts))
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=target.parent, suffix=".npz", delete=False) as f:
            np.savez(f, **arrays)  # type: ignore[arg-type]
        os.replace(f.name, target)
    except OSError:
        return
