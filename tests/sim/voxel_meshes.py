"""Closed meshes made of unit cubes, written as binary STL files, for the tests of concave
collision meshes."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

#: An L-shaped prism of three cubes: volume 3, its hull's 3.5.
L_SHAPE = ((0, 0, 0), (1, 0, 0), (0, 1, 0))
#: A U of five cubes (a notch of one cube in a 3×2 block): volume 5, its hull's 6.
U_SHAPE = ((0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (2, 1, 0))
#: One cube.
CUBE = ((0, 0, 0),)

# each face of a unit cube as the axis it faces, the side, and its corners counter-clockwise
# seen from outside
_FACES = (
    ((0, -1), ((0, 0, 0), (0, 0, 1), (0, 1, 1), (0, 1, 0))),
    ((0, 1), ((1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1))),
    ((1, -1), ((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1))),
    ((1, 1), ((0, 1, 0), (0, 1, 1), (1, 1, 1), (1, 1, 0))),
    ((2, -1), ((0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0))),
    ((2, 1), ((0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))),
)


def voxel_triangles(cells, size_m: float = 0.1) -> np.ndarray:
    """The outward-facing boundary triangles ``(F, 3, 3)`` [m] of a set of cubes of side
    ``size_m`` (a face shared by two cubes is inside and left out)."""
    filled = {tuple(c) for c in cells}
    triangles = []
    for cell in filled:
        for (axis, side), corners in _FACES:
            neighbour = list(cell)
            neighbour[axis] += side
            if tuple(neighbour) in filled:
                continue
            a, b, c, d = (np.add(cell, corner) * size_m for corner in corners)
            triangles += [(a, b, c), (a, c, d)]
    return np.array(triangles, dtype=float)


def write_stl(path: Path, triangles: np.ndarray) -> Path:
    """``triangles`` ``(F, 3, 3)`` as a binary STL file at ``path``."""
    out = bytearray(b"dqcontrol test mesh".ljust(80, b" "))
    out += struct.pack("<I", len(triangles))
    for tri in triangles:
        normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        normal /= np.linalg.norm(normal)
        out += struct.pack("<12fH", *normal, *tri.ravel(), 0)
    path.write_bytes(bytes(out))
    return path
