"""A concave collision mesh as convex parts, for MuJoCo's contacts (docs/theory.md §10.8).

MuJoCo collides every mesh as its convex hull. For a link whose mesh is concave (a hollow
housing, an elbow's recess) the hull fills space the link does not occupy, and two links
whose meshes are centimetres apart can touch as hulls: the simulated arm then pushes
against itself where the real one moves freely. A collision mesh whose hull exceeds its
own volume by more than :data:`HULL_EXCESS` is therefore split into convex parts
(approximate convex decomposition, CoACD, with the fixed :data:`COACD_SETTINGS` and seed):
each part is the hull of a piece of the mesh, so together they cover the mesh (to a few
hundredths of a millimetre: CoACD samples the surface), lie inside its hull, and hold
little space the mesh does not.

A decomposition takes a second or a few a mesh. The meshes of a robot are decomposed
together, each in a process of its own (as many at a time as there are cores), each given
:data:`TIME_LIMIT_S` of processor time (not of wall time: a loaded machine slows it, and
the outcome stays the machine's, not the moment's); a mesh that takes longer, or whose
decomposition fails, is left whole with a warning that names it. The processes run at a
lower priority (``nice`` 10), so that a control loop beside them keeps its cores. The
outcome is kept on disk (:func:`cache_dir`), keyed by the mesh file's bytes, its scale and
the settings, so a robot is decomposed once per machine.
A mesh close enough to convex is left as it is (``None``), so its simulation is exactly
what it was.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dqcontrol.extras import require

__all__ = [
    "CACHE_ENV",
    "COACD_SETTINGS",
    "HULL_EXCESS",
    "TIME_LIMIT_S",
    "WALL_LIMIT_S",
    "cache_dir",
    "convex_parts",
    "hull_excess",
    "mesh_arrays",
]

#: A mesh is split where its hull's volume exceeds the mesh's by more than this share.
HULL_EXCESS = 0.10
#: CoACD's settings: its concavity threshold, at most 16 parts, the mesh as it is (no
#: remeshing), a coarse search.
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
#: The processor time [s] a mesh's decomposition may take before the mesh is left whole.
TIME_LIMIT_S = 60.0
#: The wall time [s] after which a decomposition is stopped whatever its processor time
#: (the mesh is left whole for this model, and tried again for the next).
WALL_LIMIT_S = 600.0
#: The environment variable naming the folder the parts are kept in.
CACHE_ENV = "DQCONTROL_CACHE_DIR"
#: What a decomposition's process runs (:func:`_main`; its arguments: the mesh, its scale,
#: the output, the processor time allowed).
_CHILD = "import sys; from dqcontrol.sim.convex_parts import _main; _main(sys.argv[1:])"
#: The count kept for a mesh left whole because its decomposition failed or took too long.
_GAVE_UP = -1

Parts = tuple[np.ndarray, ...]


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
    (``inf`` for an open mesh, which encloses almost no volume; 0 for a flat one, whose hull
    has none to add)."""
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


def convex_parts(meshes: Sequence[tuple[Path, np.ndarray]]) -> list[Parts | None]:
    """The vertices of the convex parts of each mesh ``(path, scale)``, or ``None`` for a
    mesh left whole: within :data:`HULL_EXCESS` of its hull, or given up on (module
    docstring)."""
    keys = [_key(Path(path), np.asarray(scale, dtype=float)) for path, scale in meshes]
    found = [_read(key, str(path)) for key, (path, _) in zip(keys, meshes, strict=True)]
    todo = []
    for i, (path, scale) in enumerate(meshes):
        if found[i] is not None:
            continue
        vertices, triangles = mesh_arrays(Path(path), np.asarray(scale, dtype=float))
        if hull_excess(vertices, triangles) <= HULL_EXCESS:
            found[i] = ()
            _write(keys[i], ())
        else:
            todo.append(i)
    if todo:
        require("coacd", extra="sim", purpose="the convex parts of a concave collision mesh")
        done = _decompose([meshes[i] for i in todo], [keys[i] for i in todo])
        for i, (parts, why) in zip(todo, done, strict=True):
            if parts is None:
                _warn_whole(str(meshes[i][0]), why)
            found[i] = parts
    return [parts or None for parts in found]


def _decompose(
    meshes: Sequence[tuple[Path, np.ndarray]], keys: list[str]
) -> list[tuple[Parts | None, str]]:
    """The parts of ``meshes`` (``None``: left whole, and why), each decomposed in a process
    of its own, as many at a time as there are cores; each outcome kept under its key but
    for one stopped at :data:`WALL_LIMIT_S`. An interrupt stops the processes."""
    outcome: dict[str, tuple[Parts | None, str]] = {}
    waiting = list(zip(meshes, keys, strict=True))
    running: list[tuple[subprocess.Popen, str, float, Path]] = []
    with tempfile.TemporaryDirectory() as folder:
        try:
            while waiting or running:
                while waiting and len(running) < (os.cpu_count() or 1):
                    (path, scale), key = waiting.pop(0)
                    out = Path(folder) / f"{key}.npz"
                    running.append((_start(path, scale, out), key, time.monotonic(), out))
                time.sleep(0.02)
                for entry in list(running):
                    job, key, start, out = entry
                    late = time.monotonic() - start > WALL_LIMIT_S
                    if job.poll() is None and not late:
                        continue
                    running.remove(entry)
                    job.kill()  # nothing to stop if it has ended
                    outcome[key] = _outcome(job.wait(), out, late, key)
        finally:
            for job, *_ in running:
                job.kill()
                job.wait()
    return [outcome[key] for key in keys]


def _outcome(code: int, out: Path, late: bool, key: str) -> tuple[Parts | None, str]:
    """A finished decomposition's parts (kept under ``key``, unless stopped ``late``), or
    ``None`` and why."""
    if late:
        return None, f"it was stopped after {WALL_LIMIT_S:g} s of wall time (tried again later)"
    loaded = _load(out) if code == 0 else None
    parts = None if loaded is None or loaded[0] < 0 else loaded[1]
    _write(key, parts)
    return parts, "" if parts is not None else _given_up(key)


def _start(path: Path, scale: np.ndarray, out: Path) -> subprocess.Popen:
    """A process that decomposes the mesh at ``path`` (``scale``) into ``out``, within
    :data:`TIME_LIMIT_S` of processor time."""
    sizes = [repr(float(x)) for x in np.asarray(scale, dtype=float)]
    limit = repr(float(TIME_LIMIT_S))
    command = [sys.executable, "-c", _CHILD, str(Path(path)), *sizes, str(out), limit]
    return subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


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


def _load(path: Path) -> tuple[int, Parts] | None:
    """The count and the parts kept in ``path``, or ``None`` where there is no readable
    file."""
    try:
        with np.load(path) as data:
            count = int(data["count"])
            return count, tuple(data[f"part{k}"] for k in range(max(count, 0)))
    except (OSError, KeyError, ValueError):
        return None


def _read(key: str, name: str) -> Parts | None:
    """The parts kept under ``key`` (``()``: the mesh is left whole), or ``None``; a mesh
    given up on is left whole, with a warning that names it."""
    loaded = _load(_file(key))
    if loaded is None:
        return None
    count, parts = loaded
    if count == _GAVE_UP:
        _warn_whole(name, _given_up(key))
    return parts


def _given_up(key: str) -> str:
    return (
        f"its decomposition failed or took more than {TIME_LIMIT_S:g} s of processor time "
        f"(delete {_file(key)} to try again)"
    )


def _warn_whole(name: str, why: str) -> None:
    warnings.warn(
        f"collision mesh {name} is left whole (MuJoCo collides its convex hull): {why}",
        stacklevel=4,
    )


def _write(key: str, parts: Parts | None) -> None:
    """Keep ``parts`` under ``key`` (``None``: given up on), written whole and then renamed
    (a reader never sees half a file); a cache that cannot be written is skipped."""
    try:
        _write_file(_file(key), parts)
    except OSError:
        return


def _write_file(target: Path, parts: Parts | None) -> None:
    arrays: dict[str, np.ndarray] = {f"part{k}": p for k, p in enumerate(parts or ())}
    arrays["count"] = np.array(_GAVE_UP if parts is None else len(parts))
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=target.parent, suffix=".npz", delete=False) as f:
        np.savez(f, **arrays)  # type: ignore[arg-type]
    os.replace(f.name, target)


def _main(argv: list[str]) -> None:
    """One decomposition, in a process of its own: ``MESH SX SY SZ OUT.npz LIMIT_S``, at a
    lower priority and within ``LIMIT_S`` of processor time (where the system has process
    limits; elsewhere :data:`WALL_LIMIT_S` holds)."""
    if hasattr(os, "nice"):  # not on Windows
        os.nice(10)
    try:
        import resource

        limit = int(math.ceil(float(argv[5])))
        resource.setrlimit(resource.RLIMIT_CPU, (limit, limit))
    except (ImportError, ValueError, OSError):
        pass

    coacd = require("coacd", extra="sim", purpose="the convex parts of a concave collision mesh")
    path, scale, out = Path(argv[0]), np.array([float(s) for s in argv[1:4]]), Path(argv[4])
    vertices, triangles = mesh_arrays(path, scale)
    coacd.set_log_level("error")
    found = coacd.run_coacd(coacd.Mesh(vertices, triangles), **COACD_SETTINGS)
    _write_file(out, tuple(np.asarray(v, dtype=float).reshape(-1, 3) for v, _ in found))
