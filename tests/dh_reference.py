"""Independent standard-DH reference kinematics (helper for the tests, not a test module).

Written with plain numpy 4x4 homogeneous matrices and hand-written quaternion algebra; it
uses nothing from Pinocchio or from the ``dqcontrol`` package, so it can serve as an
external oracle for the URDF-based kinematics.

Conventions
-----------
* Standard DH: link i's transform is ``Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``; DH frame 0 is
  ``base @ Tz(base_offset_z)`` and frame n (the flange) is frame 0 times all link transforms.
* Geometric Jacobian rows are ``[v; w]``: linear velocity of the flange origin and angular
  velocity, both in base axes (Pinocchio's LOCAL_WORLD_ALIGNED convention).
* vec8 of a unit dual quaternion is ``[r_w, r_x, r_y, r_z, d_w, d_x, d_y, d_z]`` with
  ``d = 0.5 * t * r`` (t the translation as a pure quaternion). The rotation quaternion from
  :func:`rotation_to_quaternion` is sign-normalised: ``r_w > 0``, or, for a half-turn
  (``r_w == 0``), the first non-zero of ``r_x, r_y, r_z`` positive. :func:`dh_pose_vec8` follows
  that rule, and :func:`dh_pose_jacobian_vec8` is the derivative of exactly that vec8 (same
  sign), except on the measure-zero set of half-turns where the sign rule is discontinuous.

Every kinematic function accepts the DH parameters either positionally
(``dh_fkm(q, d, a, alpha)``) or as ``dh_fkm(q, **LBR4P_DH)``; ``base_offset_z`` is applied on
top of ``base`` (frame 0 = ``base @ Tz(base_offset_z)``).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "LBR4P_DH",
    "LBR4P_FLANGE_AT_ZERO",
    "dh_link_transform",
    "dh_frames",
    "dh_fkm",
    "dh_geometric_jacobian",
    "quat_mul",
    "quat_conj",
    "rotation_to_quaternion",
    "quaternion_to_rotation",
    "dq_mul",
    "pose_to_vec8",
    "dh_pose_vec8",
    "dh_pose_jacobian_vec8",
    "finite_difference_jacobian",
    "lbr4p_fkm",
    "lbr4p_frames",
    "lbr4p_geometric_jacobian",
    "lbr4p_pose_vec8",
    "lbr4p_pose_jacobian_vec8",
]

_PI2 = np.pi / 2

#: The thesis's LBR4p (eq. 4.2-4.3): standard DH, DH frame 0 0.51 m above the robot base.
LBR4P_DH = dict(
    d=(0.2, 0.0, 0.4, 0.0, 0.39, 0.0, 0.078),
    a=(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    alpha=(_PI2, -_PI2, _PI2, -_PI2, _PI2, -_PI2, 0.0),
    base_offset_z=0.51,
)

#: Flange position in the base frame at q = 0 (0.51 + 0.2 + 0.4 + 0.39 + 0.078).
LBR4P_FLANGE_AT_ZERO = np.array([0.0, 0.0, 1.578])


# --------------------------------------------------------------------------------------------
# Homogeneous matrices
# --------------------------------------------------------------------------------------------
def _rot_z(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    T = np.eye(4)
    T[0, 0], T[0, 1], T[1, 0], T[1, 1] = c, -s, s, c
    return T


def _rot_x(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    T = np.eye(4)
    T[1, 1], T[1, 2], T[2, 1], T[2, 2] = c, -s, s, c
    return T


def _trans(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _check(q, d, a, alpha):
    q = np.asarray(q, dtype=float).reshape(-1)
    d = np.asarray(d, dtype=float).reshape(-1)
    a = np.asarray(a, dtype=float).reshape(-1)
    alpha = np.asarray(alpha, dtype=float).reshape(-1)
    n = q.size
    if not (d.size == a.size == alpha.size == n):
        raise ValueError(
            f"q, d, a, alpha must have equal length, got {n}, {d.size}, {a.size}, {alpha.size}"
        )
    return q, d, a, alpha


def _frame0(base, base_offset_z) -> np.ndarray:
    B = np.eye(4) if base is None else np.asarray(base, dtype=float).reshape(4, 4)
    return B @ _trans(0.0, 0.0, float(base_offset_z))


def dh_link_transform(q_i: float, d_i: float, a_i: float, alpha_i: float) -> np.ndarray:
    """``Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`` as a 4x4 homogeneous matrix."""
    return _rot_z(q_i) @ _trans(0.0, 0.0, d_i) @ _trans(a_i, 0.0, 0.0) @ _rot_x(alpha_i)


def dh_frames(q, d, a, alpha, base=None, base_offset_z: float = 0.0) -> list[np.ndarray]:
    """DH frames 0..n in the base frame (list of n + 1 4x4 matrices)."""
    q, d, a, alpha = _check(q, d, a, alpha)
    T = _frame0(base, base_offset_z)
    frames = [T.copy()]
    for i in range(q.size):
        T = T @ dh_link_transform(q[i], d[i], a[i], alpha[i])
        frames.append(T.copy())
    return frames


def dh_fkm(q, d, a, alpha, base=None, base_offset_z: float = 0.0) -> np.ndarray:
    """Flange pose (DH frame n) in the base frame, 4x4."""
    return dh_frames(q, d, a, alpha, base, base_offset_z)[-1]


def dh_geometric_jacobian(q, d, a, alpha, base=None, base_offset_z: float = 0.0) -> np.ndarray:
    """6 x n geometric Jacobian ``[v; w]`` of the flange, base axes, revolute joints.

    Column i: ``[z_{i-1} x (p_n - p_{i-1}); z_{i-1}]`` from the DH frames.
    """
    frames = dh_frames(q, d, a, alpha, base, base_offset_z)
    n = len(frames) - 1
    p_n = frames[-1][:3, 3]
    J = np.zeros((6, n))
    for i in range(n):
        z = frames[i][:3, 2]
        p = frames[i][:3, 3]
        J[:3, i] = np.cross(z, p_n - p)
        J[3:, i] = z
    return J


# --------------------------------------------------------------------------------------------
# Quaternions and dual quaternions (own implementation)
# --------------------------------------------------------------------------------------------
def quat_mul(p, q) -> np.ndarray:
    """Hamilton product ``p q`` of quaternions ``[w, x, y, z]``."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ]
    )


def quat_conj(q) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]], dtype=float)


def _normalise_sign(r: np.ndarray) -> np.ndarray:
    for c in r:  # first non-zero component (w first) made positive
        if c > 0.0:
            return r
        if c < 0.0:
            return -r
    return r


def rotation_to_quaternion(R) -> np.ndarray:
    """Unit quaternion ``[w, x, y, z]`` of a rotation matrix (Shepperd's method).

    Picks the largest of ``4w^2, 4x^2, 4y^2, 4z^2`` (from the trace and the diagonal) as the
    pivot so that the square root and the division are always well conditioned; the result is
    then sign-normalised (``w > 0``, see module docstring).
    """
    R = np.asarray(R, dtype=float)[:3, :3]
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    # 4 * (squared component) candidates: w, x, y, z
    cand = np.array(
        [
            1.0 + tr,
            1.0 + R[0, 0] - R[1, 1] - R[2, 2],
            1.0 - R[0, 0] + R[1, 1] - R[2, 2],
            1.0 - R[0, 0] - R[1, 1] + R[2, 2],
        ]
    )
    k = int(np.argmax(cand))
    s = 2.0 * np.sqrt(max(cand[k], 0.0))  # = 4 |component k|
    if k == 0:
        r = np.array(
            [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
        )
    elif k == 1:
        r = np.array(
            [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
        )
    elif k == 2:
        r = np.array(
            [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
        )
    else:
        r = np.array(
            [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
        )
    r = r / np.linalg.norm(r)
    return _normalise_sign(r)


def quaternion_to_rotation(r) -> np.ndarray:
    """3x3 rotation matrix of a unit quaternion ``[w, x, y, z]``."""
    w, x, y, z = np.asarray(r, dtype=float) / np.linalg.norm(r)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def dq_mul(x, y) -> np.ndarray:
    """Dual-quaternion product of two vec8: ``(r1 + e d1)(r2 + e d2)``."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    r = quat_mul(x[:4], y[:4])
    d = quat_mul(x[:4], y[4:]) + quat_mul(x[4:], y[:4])
    return np.concatenate([r, d])


def pose_to_vec8(T) -> np.ndarray:
    """vec8 of the unit dual quaternion of a 4x4 pose: ``[r; 0.5 t r]``."""
    T = np.asarray(T, dtype=float)
    r = rotation_to_quaternion(T[:3, :3])
    t = np.array([0.0, T[0, 3], T[1, 3], T[2, 3]])
    return np.concatenate([r, 0.5 * quat_mul(t, r)])


def _dq_rot(axis: int, theta: float) -> np.ndarray:
    r = np.zeros(8)
    r[0] = np.cos(0.5 * theta)
    r[1 + axis] = np.sin(0.5 * theta)
    return r


def _dq_trans(x: float, y: float, z: float) -> np.ndarray:
    return np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.5 * x, 0.5 * y, 0.5 * z])


# --------------------------------------------------------------------------------------------
# Pose and pose Jacobian in vec8
# --------------------------------------------------------------------------------------------
def dh_pose_vec8(q, d, a, alpha, base=None, base_offset_z: float = 0.0) -> np.ndarray:
    """vec8 of the flange pose (from the 4x4 FKM, own Shepperd conversion, sign ``r_w > 0``)."""
    return pose_to_vec8(dh_fkm(q, d, a, alpha, base, base_offset_z))


def dh_pose_jacobian_vec8(q, d, a, alpha, base=None, base_offset_z: float = 0.0) -> np.ndarray:
    """8 x n pose Jacobian ``d vec8(x) / dq`` derived directly on the DH chain.

    ``x = x_0 x_1(q_1) ... x_n(q_n)`` with ``x_i = rz(q_i) tz(d_i) tx(a_i) rx(alpha_i)`` as dual
    quaternions and ``rz(q) = cos(q/2) + k sin(q/2)``, so ``d rz / dq = rz (k / 2)`` and the
    product rule gives column i as ``x_0 .. x_{i-1} rz(q_i) (k/2) [rest of x_i] x_{i+1} .. x_n``.
    No geometric Jacobian or frame-Jacobian mapping is involved. The overall sign is matched
    to :func:`dh_pose_vec8`.
    """
    q, d, a, alpha = _check(q, d, a, alpha)
    n = q.size
    x0 = pose_to_vec8(_frame0(base, base_offset_z))
    half_k = np.array([0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0])
    rz = [_dq_rot(2, qi) for qi in q]
    rest = [
        dq_mul(dq_mul(_dq_trans(0.0, 0.0, d[i]), _dq_trans(a[i], 0.0, 0.0)), _dq_rot(0, alpha[i]))
        for i in range(n)
    ]
    links = [dq_mul(rz[i], rest[i]) for i in range(n)]

    # prefix[i] = x_0 x_1 .. x_i (prefix[0] = x_0); suffix[i] = x_{i+1} .. x_n (empty = 1)
    prefix = [x0]
    for i in range(n):
        prefix.append(dq_mul(prefix[-1], links[i]))
    one = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])
    suffix = [one] * (n + 1)
    for i in range(n - 1, -1, -1):
        suffix[i] = dq_mul(links[i], suffix[i + 1])

    J = np.zeros((8, n))
    for i in range(n):
        dxi = dq_mul(dq_mul(rz[i], half_k), rest[i])  # d x_i / d q_i
        J[:, i] = dq_mul(dq_mul(prefix[i], dxi), suffix[i + 1])

    # the product chain may land on -x relative to the sign-normalised dh_pose_vec8
    x_chain = prefix[-1]
    x_ref = dh_pose_vec8(q, d, a, alpha, base, base_offset_z)
    if float(np.dot(x_chain, x_ref)) < 0.0:
        J = -J
    return J


def finite_difference_jacobian(fun, q, h: float = 1e-6) -> np.ndarray:
    """Central finite differences of a vector function ``fun(q)``, column by column."""
    q = np.asarray(q, dtype=float).reshape(-1)
    f0 = np.asarray(fun(q))
    J = np.zeros((f0.size, q.size))
    for i in range(q.size):
        e = np.zeros_like(q)
        e[i] = h
        J[:, i] = (np.asarray(fun(q + e)) - np.asarray(fun(q - e))) / (2.0 * h)
    return J


# --------------------------------------------------------------------------------------------
# LBR4p shorthands (world/base_link frame of robots/lbr4p/lbr4p.urdf)
# --------------------------------------------------------------------------------------------
def lbr4p_frames(q) -> list[np.ndarray]:
    return dh_frames(q, **LBR4P_DH)


def lbr4p_fkm(q) -> np.ndarray:
    return dh_fkm(q, **LBR4P_DH)


def lbr4p_geometric_jacobian(q) -> np.ndarray:
    return dh_geometric_jacobian(q, **LBR4P_DH)


def lbr4p_pose_vec8(q) -> np.ndarray:
    return dh_pose_vec8(q, **LBR4P_DH)


def lbr4p_pose_jacobian_vec8(q) -> np.ndarray:
    return dh_pose_jacobian_vec8(q, **LBR4P_DH)
