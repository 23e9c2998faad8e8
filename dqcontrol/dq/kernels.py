"""Pinocchio's placement and frame Jacobian to a ``vec8`` pose and 8×n pose Jacobian, compiled.

docs/theory.md §2 in scalar form: from Pinocchio's ``XYZQUAT`` ``[t, r_x, r_y, r_z, r_w]``
and its 6×n frame Jacobian in ``LOCAL_WORLD_ALIGNED`` (rows ``[Jv; Jw]``, the linear
velocity of the frame origin and the angular velocity, both in world axes)::

    r   (sign chosen so that r_w ≥ 0)
    d   = ½ t r                          (t as the pure quaternion (0, t))
    J_r = ½ ω r                 per column: ṙ when the joint moves at 1 rad/s
    J_d = ½ (v r + t J_r)       ḋ = ½ (ṫ r + t ṙ)

The quaternion products are written out on floats and compiled with Numba (``cache=True``:
compiled once per machine, then loaded from ``__pycache__``): at 1 kHz the work is a few
hundred flops, and the cost of one pose + Jacobian is then Pinocchio's call plus one
dispatch instead of a chain of small numpy calls. ``tests/model/test_robot.py`` checks the
result against an independent DH chain and finite differences, ``tests/dq/test_kernels.py``
against the Hamilton-operator form.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = [
    "pose_from_xyzquat",
    "pose_jacobian_batch",
    "pose_jacobian_from_xyzquat",
    "pose_jacobian_into",
]

_NO_COLUMNS = (np.zeros((6, 0)), np.zeros((8, 0)))


@compiled
def pose_jacobian_into(v: np.ndarray, j6: np.ndarray, x: np.ndarray, jac: np.ndarray) -> None:
    """Write ``vec8`` of the XYZQUAT ``v`` into ``x`` (8,) and its pose Jacobian into
    ``jac`` (8, n), ``j6`` the (6, n) LOCAL_WORLD_ALIGNED frame Jacobian."""
    tx, ty, tz = v[0], v[1], v[2]
    rx, ry, rz, rw = v[3], v[4], v[5], v[6]
    if rw < 0.0:  # the sign convention of the whole package: r_w ≥ 0
        rx, ry, rz, rw = -rx, -ry, -rz, -rw
    x[0] = rw
    x[1] = rx
    x[2] = ry
    x[3] = rz
    # d = ½ (0, t) r
    x[4] = 0.5 * (-tx * rx - ty * ry - tz * rz)
    x[5] = 0.5 * (tx * rw + ty * rz - tz * ry)
    x[6] = 0.5 * (-tx * rz + ty * rw + tz * rx)
    x[7] = 0.5 * (tx * ry - ty * rx + tz * rw)
    for k in range(j6.shape[1]):
        vx, vy, vz = j6[0, k], j6[1, k], j6[2, k]
        wx, wy, wz = j6[3, k], j6[4, k], j6[5, k]
        # J_r = ½ (0, ω) r
        a0 = 0.5 * (-wx * rx - wy * ry - wz * rz)
        a1 = 0.5 * (wx * rw + wy * rz - wz * ry)
        a2 = 0.5 * (-wx * rz + wy * rw + wz * rx)
        a3 = 0.5 * (wx * ry - wy * rx + wz * rw)
        jac[0, k] = a0
        jac[1, k] = a1
        jac[2, k] = a2
        jac[3, k] = a3
        # J_d = ½ ((0, v) r + (0, t) J_r)
        jac[4, k] = 0.5 * ((-vx * rx - vy * ry - vz * rz) + (-tx * a1 - ty * a2 - tz * a3))
        jac[5, k] = 0.5 * ((vx * rw + vy * rz - vz * ry) + (tx * a0 + ty * a3 - tz * a2))
        jac[6, k] = 0.5 * ((-vx * rz + vy * rw + vz * rx) + (-tx * a3 + ty * a0 + tz * a1))
        jac[7, k] = 0.5 * ((vx * ry - vy * rx + vz * rw) + (tx * a2 - ty * a1 + tz * a0))


@compiled
def pose_jacobian_from_xyzquat(v: np.ndarray, j6: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(vec8 (8,), pose Jacobian (8, n))`` from Pinocchio's ``SE3ToXYZQUAT`` of the
    frame (7,) and its (6, n) ``LOCAL_WORLD_ALIGNED`` frame Jacobian; new arrays."""
    x = np.empty(8)
    jac = np.empty((8, j6.shape[1]))
    pose_jacobian_into(v, j6, x, jac)
    return x, jac


def pose_from_xyzquat(v: np.ndarray) -> np.ndarray:
    """``vec8`` (8,) of Pinocchio's ``SE3ToXYZQUAT`` of a frame (7,), as
    :func:`pose_jacobian_from_xyzquat` gives it; a new array."""
    x = np.empty(8)
    pose_jacobian_into(v, _NO_COLUMNS[0], x, _NO_COLUMNS[1])
    return x


@compiled
def pose_jacobian_batch(vs: np.ndarray, j6s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pose_jacobian_from_xyzquat` for N frames: ``vs`` (N, 7), ``j6s`` (N, 6, n)
    → ``(N, 8)``, ``(N, 8, n)``."""
    count = vs.shape[0]
    xs = np.empty((count, 8))
    jacs = np.empty((count, 8, j6s.shape[2]))
    for i in range(count):
        pose_jacobian_into(vs[i], j6s[i], xs[i], jacs[i])
    return xs, jacs
