"""The convex parts of a concave collision mesh: they cover the mesh, stay inside its hull,
hold little more than its volume, and are computed once (dqcontrol.sim.convex_parts)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull
from sim.voxel_meshes import CUBE, L_SHAPE, U_SHAPE, voxel_triangles, write_stl

from dqcontrol.sim import convex_parts as cp

pytest.importorskip("coacd")


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv(cp.CACHE_ENV, str(folder))
    return folder


def _mesh(tmp_path, cells, name="mesh.stl", size_m=0.1):
    return write_stl(tmp_path / name, voxel_triangles(cells, size_m))


def _parts(path, scale=(1.0, 1.0, 1.0)):
    return cp.convex_parts([(path, np.asarray(scale, dtype=float))])[0]


def _outside_m(points: np.ndarray, hulls: list[ConvexHull]) -> float:
    """How far the farthest of ``points`` is outside the union of ``hulls`` [m] (≤ 0:
    every point inside one of them)."""
    beyond = np.full(len(points), np.inf)
    for hull in hulls:
        eq = hull.equations
        beyond = np.minimum(beyond, (points @ eq[:, :3].T + eq[:, 3]).max(axis=1))
    return float(beyond.max())


def test_the_hull_excess_of_voxel_shapes():
    for cells, excess in ((CUBE, 0.0), (L_SHAPE, 0.5 / 3.0), (U_SHAPE, 0.2)):
        triangles = voxel_triangles(cells)
        vertices = triangles.reshape(-1, 3)
        faces = np.arange(len(vertices)).reshape(-1, 3)
        assert cp.hull_excess(vertices, faces) == pytest.approx(excess, abs=1e-9)


def test_an_open_mesh_counts_as_concave():
    triangles = voxel_triangles(CUBE)[:-2]  # one face missing: no volume enclosed
    vertices = triangles.reshape(-1, 3)
    assert cp.hull_excess(vertices, np.arange(len(vertices)).reshape(-1, 3)) > 0.0


def test_the_mesh_is_read_as_the_collision_model_reads_it(tmp_path):
    vertices, triangles = cp.mesh_arrays(_mesh(tmp_path, L_SHAPE), np.array([2.0, 1.0, 1.0]))
    assert triangles.shape == (28, 3)
    np.testing.assert_allclose(vertices.max(axis=0), [0.4, 0.2, 0.1], atol=1e-7)


@pytest.mark.parametrize("cells", [L_SHAPE, U_SHAPE], ids=["L", "U"])
def test_the_parts_cover_the_mesh_inside_its_hull(tmp_path, cells):
    path = _mesh(tmp_path, cells)
    vertices, triangles = cp.mesh_arrays(path, np.ones(3))
    parts = _parts(path)
    assert parts is not None and len(parts) >= 2
    hulls = [ConvexHull(p) for p in parts]
    assert _outside_m(vertices, hulls) <= 5e-5  # every point of the mesh in a part, to 0.05 mm
    whole = ConvexHull(vertices)
    assert _outside_m(np.vstack(parts), [whole]) <= 1e-6  # every part inside the hull
    volume = len(cells) * 0.1**3
    assert sum(h.volume for h in hulls) <= (1.0 + cp.HULL_EXCESS) * volume
    # the notch is free: its centre is in no part
    notch = {L_SHAPE: (0.15, 0.15, 0.05), U_SHAPE: (0.15, 0.15, 0.05)}[cells]
    assert _outside_m(np.array([notch]), hulls) > 0.01


def test_a_convex_mesh_is_left_whole(tmp_path):
    assert _parts(_mesh(tmp_path, CUBE)) is None


def test_the_parts_are_computed_once(tmp_path, cache, monkeypatch):
    path = _mesh(tmp_path, L_SHAPE)
    first = _parts(path)
    assert len(list((cache / "convex_parts").glob("*.npz"))) == 1

    def refuse(*args, **kwargs):
        raise AssertionError("decomposed again")

    monkeypatch.setattr(cp, "_decompose", refuse)
    again = _parts(path)
    assert first is not None and again is not None
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    # another scale is another mesh
    with pytest.raises(AssertionError, match="decomposed again"):
        _parts(path, (2.0, 2.0, 2.0))


def test_a_convex_mesh_is_remembered_as_whole(tmp_path, monkeypatch):
    path = _mesh(tmp_path, CUBE)
    assert _parts(path) is None
    monkeypatch.setattr(cp, "mesh_arrays", lambda *a: pytest.fail("read again"))
    assert _parts(path) is None


def test_a_cache_that_cannot_be_written_is_skipped(tmp_path, monkeypatch):
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")  # the cache's folder cannot be made
    monkeypatch.setenv(cp.CACHE_ENV, str(blocked))
    parts = _parts(_mesh(tmp_path, L_SHAPE))
    assert parts is not None and len(parts) >= 2


def test_the_cache_folder(monkeypatch, tmp_path):
    monkeypatch.delenv(cp.CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert cp.cache_dir() == tmp_path / "dqcontrol"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cp.cache_dir() == tmp_path / "home" / ".cache" / "dqcontrol"


def test_the_meshes_of_a_robot_are_decomposed_together(tmp_path):
    meshes = [
        (_mesh(tmp_path, L_SHAPE, "l.stl"), np.ones(3)),
        (_mesh(tmp_path, CUBE, "cube.stl"), np.ones(3)),
        (_mesh(tmp_path, U_SHAPE, "u.stl"), np.ones(3)),
    ]
    l_parts, cube, u_parts = cp.convex_parts(meshes)
    assert cube is None
    assert l_parts is not None and u_parts is not None and len(u_parts) > len(l_parts) - 1
    for (path, scale), parts in zip(meshes, (l_parts, u_parts), strict=False):
        vertices = cp.mesh_arrays(path, scale)[0]
        if parts is not None:
            assert _outside_m(vertices, [ConvexHull(p) for p in parts]) <= 5e-5


def test_a_decomposition_past_the_time_limit_leaves_the_mesh_whole(tmp_path, monkeypatch):
    monkeypatch.setattr(cp, "TIME_LIMIT_S", 0.0)  # no processor time at all
    path = _mesh(tmp_path, L_SHAPE)
    with pytest.warns(UserWarning, match=r"mesh\.stl is left whole.*more than 0 s"):
        assert _parts(path) is None
    # remembered: not tried again, and said again
    monkeypatch.setattr(cp, "_decompose", lambda *a: pytest.fail("tried again"))
    with pytest.warns(UserWarning, match="convex hull"):
        assert _parts(path) is None


def test_a_decomposition_stopped_on_the_wall_clock_is_tried_again(tmp_path, monkeypatch):
    monkeypatch.setattr(cp, "WALL_LIMIT_S", 0.0)
    path = _mesh(tmp_path, L_SHAPE)
    with pytest.warns(UserWarning, match="wall time"):
        assert _parts(path) is None
    monkeypatch.setattr(cp, "WALL_LIMIT_S", 600.0)
    parts = _parts(path)  # nothing was kept: decomposed now
    assert parts is not None and len(parts) >= 2


def test_without_coacd_a_concave_mesh_asks_for_the_sim_extra(tmp_path, monkeypatch):
    from dqcontrol.errors import MissingExtraError

    def missing(module, *, extra, purpose):
        raise MissingExtraError(f"{purpose} needs {module} ([{extra}] extra)")

    monkeypatch.setattr(cp, "require", missing)
    with pytest.raises(MissingExtraError, match=r"coacd \(\[sim\] extra\)"):
        _parts(_mesh(tmp_path, L_SHAPE))
    assert _parts(_mesh(tmp_path, CUBE, "cube.stl")) is None  # a convex one needs nothing
