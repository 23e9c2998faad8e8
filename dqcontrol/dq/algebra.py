"""Quaternion and dual-quaternion algebra on plain numpy arrays.

Conventions (docs/theory.md §1): ``vec4 = [w, x, y, z]``;
``vec8 = [r_w, r_x, r_y, r_z, d_w, d_x, d_y, d_z]`` for ``x = r + ε d`` with ``d = ½ t r``.
Products follow the thesis's Hamilton operators (eq. 2.5, 2.18):
``vec4(a b) = H+4(a) vec4(b) = H-4(b) vec4(a)`` and likewise ``H±8`` for ``vec8``.

The elementwise functions (``qmul``, ``dq_mul``, ``dq_conj`` ...) broadcast over leading axes,
so a batch of N poses is an ``(N, 8)`` array.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from dqcontrol.errors import ParameterError

__all__ = [
    "C4",
    "C8",
    "align_sign",
    "dq_conj",
    "dq_from_matrix",
    "dq_from_rt",
    "dq_from_se3",
    "dq_from_translation",
    "dq_inv",
    "dq_is_unit",
    "dq_mul",
    "dq_norm",
    "dq_normalize",
    "dq_to_matrix",
    "dq_to_se3",
    "hamiplus4",
    "hamiplus8",
    "haminus4",
    "haminus8",
    "pose_error",
    "qconj",
    "qfrom_axis_angle",
    "qfrom_matrix",
    "qmul",
    "qto_matrix",
    "rotation",
    "rotation_angle",
    "rotation_axis",
    "translation",
]

#: ``vec4(q*) = C4 vec4(q)``.
C4 = np.diag([1.0, -1.0, -1.0, -1.0])
#: ``vec8(x*) = C8 vec8(x)`` (thesis eq. 2.20–2.21).
C8 = np.diag([1.0, -1.0, -1.0, -1.0, 1.0, -1.0, -1.0, -1.0])

_CONJ4 = np.array([1.0, -1.0, -1.0, -1.0])
_HP4: np.ndarray | None = None  # set below, once hamiplus4 exists
_CONJ8 = np.array([1.0, -1.0, -1.0, -1.0, 1.0, -1.0, -1.0, -1.0])


# --------------------------------------------------------------------------- quaternions
def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a b`` of quaternions ``[..., 4]`` (broadcasts)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.ndim == 1 and b.ndim == 1 and _HP4 is not None:
        return (_HP4 @ a).reshape(4, 4) @ b
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        axis=-1,
    )


def qconj(q: np.ndarray) -> np.ndarray:
    """Quaternion conjugate ``q*`` (broadcasts)."""
    return np.asarray(q, dtype=float) * _CONJ4


def hamiplus4(q: np.ndarray) -> np.ndarray:
    """``H+4(q)`` (4×4) with ``vec4(q b) = H+4(q) vec4(b)`` (thesis eq. 2.5)."""
    w, x, y, z = (float(c) for c in q)
    return np.array(
        [
            [w, -x, -y, -z],
            [x, w, -z, y],
            [y, z, w, -x],
            [z, -y, x, w],
        ]
    )


def haminus4(q: np.ndarray) -> np.ndarray:
    """``H-4(q)`` (4×4) with ``vec4(a q) = H-4(q) vec4(a)`` (thesis eq. 2.5)."""
    w, x, y, z = (float(c) for c in q)
    return np.array(
        [
            [w, -x, -y, -z],
            [x, w, z, -y],
            [y, -z, w, x],
            [z, y, -x, w],
        ]
    )


def qfrom_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``[w, x, y, z]`` of a rotation matrix (sign chosen with ``w ≥ 0``)."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        raise ParameterError(f"rotation matrix must have shape (3, 3), got {R.shape}")
    xyzw = pin.Quaternion(R).coeffs()
    q = np.array([xyzw[3], xyzw[0], xyzw[1], xyzw[2]])
    q /= np.linalg.norm(q)
    return -q if q[0] < 0.0 else q


def qto_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion ``[w, x, y, z]``."""
    w, x, y, z = (float(c) for c in q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def qfrom_axis_angle(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Unit quaternion of a rotation by ``angle_rad`` [rad] about ``axis`` (normalised here)."""
    axis = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(axis)
    if axis.shape != (3,) or not np.isfinite(norm) or norm == 0.0:
        raise ParameterError(f"rotation axis must be a finite non-zero 3-vector, got {axis!r}")
    half = 0.5 * float(angle_rad)
    return np.concatenate(([np.cos(half)], np.sin(half) * axis / norm))


# ------------------------------------------------------------------ dual quaternions
def dq_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dual-quaternion product ``a b`` of ``vec8`` arrays (broadcasts over leading axes)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.ndim == 1 and b.ndim == 1:
        return hamiplus8(a) @ b
    ra, da = a[..., :4], a[..., 4:]
    rb, db = b[..., :4], b[..., 4:]
    return np.concatenate((qmul(ra, rb), qmul(ra, db) + qmul(da, rb)), axis=-1)


def dq_conj(x: np.ndarray) -> np.ndarray:
    """Dual-quaternion conjugate ``x* = r* + ε d*`` (broadcasts)."""
    return np.asarray(x, dtype=float) * _CONJ8


def dq_norm(x: np.ndarray) -> np.ndarray:
    """Dual-number norm ``‖x‖ = |r| + ε (r·d)/|r|`` as ``[primary, dual]`` (broadcasts).

    A unit dual quaternion has norm ``[1, 0]``.
    """
    x = np.asarray(x, dtype=float)
    r, d = x[..., :4], x[..., 4:]
    nr = np.linalg.norm(r, axis=-1)
    return np.stack((nr, np.sum(r * d, axis=-1) / nr), axis=-1)


def dq_is_unit(x: np.ndarray, tol: float = 1e-9) -> bool:
    """Whether ``x`` is a unit dual quaternion (``|r| = 1`` and ``r·d = 0``) within ``tol``."""
    n = dq_norm(x)
    return bool(np.all(np.abs(n[..., 0] - 1.0) <= tol) and np.all(np.abs(n[..., 1]) <= tol))


def dq_inv(x: np.ndarray) -> np.ndarray:
    """Multiplicative inverse ``(r + ε d)⁻¹ = r⁻¹ - ε r⁻¹ d r⁻¹``; equals ``x*`` for unit ``x``."""
    x = np.asarray(x, dtype=float)
    r, d = x[..., :4], x[..., 4:]
    n2 = np.sum(r * r, axis=-1, keepdims=True)
    if np.any(n2 == 0.0):
        raise ParameterError("dual quaternion with zero primary part has no inverse")
    rinv = qconj(r) / n2
    return np.concatenate((rinv, -qmul(qmul(rinv, d), rinv)), axis=-1)


def dq_normalize(x: np.ndarray) -> np.ndarray:
    """Nearest unit dual quaternion: ``r/|r|`` and the dual part made orthogonal to it."""
    x = np.asarray(x, dtype=float)
    r, d = x[..., :4], x[..., 4:]
    nr = np.linalg.norm(r, axis=-1, keepdims=True)
    r = r / nr
    d = d / nr
    d = d - np.sum(r * d, axis=-1, keepdims=True) * r
    return np.concatenate((r, d), axis=-1)


def _hamilton8_slow(x: np.ndarray, ham4) -> np.ndarray:
    hr = ham4(x[:4])
    out = np.zeros((8, 8))
    out[:4, :4] = hr
    out[4:, 4:] = hr
    out[4:, :4] = ham4(x[4:])
    return out


def _linear_tensor(fn, size: int) -> np.ndarray:
    """Constant matrix ``T`` with ``fn(x).ravel() = T x`` for a matrix ``fn`` linear in x."""
    eye = np.eye(size)
    return np.stack([fn(eye[i]).ravel() for i in range(size)], axis=1)


#: H+4, H-4, H+8, H-8 are linear in their argument: ``H(x) = (T x).reshape``. One product
#: instead of building the matrix entry by entry (the controllers call them every step).
_HP4 = _linear_tensor(hamiplus4, 4)
_HP8 = _linear_tensor(lambda x: _hamilton8_slow(x, hamiplus4), 8)
_HM8 = _linear_tensor(lambda x: _hamilton8_slow(x, haminus4), 8)


def hamiplus8(x: np.ndarray) -> np.ndarray:
    """``H+8(x)`` (8×8) with ``vec8(x b) = H+8(x) vec8(b)`` (thesis eq. 2.18)."""
    return (_HP8 @ np.asarray(x, dtype=float)).reshape(8, 8)


def haminus8(x: np.ndarray) -> np.ndarray:
    """``H-8(x)`` (8×8) with ``vec8(a x) = H-8(x) vec8(a)`` (thesis eq. 2.18)."""
    return (_HM8 @ np.asarray(x, dtype=float)).reshape(8, 8)


# ------------------------------------------------------------------ poses
def dq_from_rt(r: np.ndarray, t_m: np.ndarray) -> np.ndarray:
    """Unit dual quaternion from rotation quaternion ``r`` and translation ``t_m`` [m]."""
    r = np.asarray(r, dtype=float)
    t_m = np.asarray(t_m, dtype=float)
    tq = np.concatenate((np.zeros(t_m.shape[:-1] + (1,)), t_m), axis=-1)
    return np.concatenate((r, 0.5 * qmul(tq, r)), axis=-1)


def dq_from_translation(t_m: np.ndarray) -> np.ndarray:
    """Pure translation ``1 + ε ½ t`` by ``t_m`` [m]."""
    t_m = np.asarray(t_m, dtype=float)
    return np.concatenate(([1.0, 0.0, 0.0, 0.0, 0.0], 0.5 * t_m))


def rotation(x: np.ndarray) -> np.ndarray:
    """Rotation quaternion (primary part) of a unit dual quaternion (broadcasts)."""
    return np.asarray(x, dtype=float)[..., :4].copy()


def translation(x: np.ndarray) -> np.ndarray:
    """Translation ``t = 2 d r*`` [m] of a unit dual quaternion, as a 3-vector (broadcasts)."""
    x = np.asarray(x, dtype=float)
    return (2.0 * qmul(x[..., 4:], qconj(x[..., :4])))[..., 1:]


def rotation_angle(x: np.ndarray) -> np.ndarray | float:
    """Rotation angle [rad] in ``[0, π]`` of a unit (dual) quaternion; ``x`` and ``-x`` agree.

    Accepts ``vec8`` or ``vec4`` (broadcasts). Uses ``atan2`` so it is exact near 0 and π.
    """
    x = np.asarray(x, dtype=float)
    r = x[..., :4]
    return 2.0 * np.arctan2(np.linalg.norm(r[..., 1:], axis=-1), np.abs(r[..., 0]))


def rotation_axis(x: np.ndarray) -> np.ndarray:
    """Unit rotation axis of a unit (dual) quaternion; ``[0, 0, 1]`` for the identity.

    The axis is oriented so that the angle of :func:`rotation_angle` (in ``[0, π]``) is a
    right-handed rotation about it.
    """
    x = np.asarray(x, dtype=float)
    r = x[:4] if x[0] >= 0.0 else -x[:4]
    v = r[1:]
    n = np.linalg.norm(v)
    if n < 1e-15:
        return np.array([0.0, 0.0, 1.0])
    return v / n


def dq_from_se3(placement: pin.SE3) -> np.ndarray:
    """``vec8`` of a Pinocchio ``SE3`` placement (rotation with ``w ≥ 0``)."""
    xyzquat = pin.SE3ToXYZQUAT(placement)
    r = np.array([xyzquat[6], xyzquat[3], xyzquat[4], xyzquat[5]])
    if r[0] < 0.0:
        r = -r
    return dq_from_rt(r, xyzquat[:3])


def dq_to_se3(x: np.ndarray) -> pin.SE3:
    """Pinocchio ``SE3`` of a unit dual quaternion ``vec8``."""
    x = np.asarray(x, dtype=float)
    if x.shape != (8,):
        raise ParameterError(f"vec8 must have shape (8,), got {x.shape}")
    return pin.SE3(qto_matrix(x[:4]), translation(x))


def dq_from_matrix(T: np.ndarray) -> np.ndarray:
    """``vec8`` of a 4×4 homogeneous transform."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4):
        raise ParameterError(f"homogeneous transform must have shape (4, 4), got {T.shape}")
    return dq_from_rt(qfrom_matrix(T[:3, :3]), T[:3, 3])


def dq_to_matrix(x: np.ndarray) -> np.ndarray:
    """4×4 homogeneous transform of a unit dual quaternion."""
    out = np.eye(4)
    out[:3, :3] = qto_matrix(x[:4])
    out[:3, 3] = translation(x)
    return out


def align_sign(
    x: np.ndarray, reference: np.ndarray, jacobian: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray | None]:
    """Flip ``x`` (and its Jacobian with it) so that ``vec8(x)·vec8(reference) ≥ 0``.

    ``x`` and ``-x`` are the same pose (docs/theory.md §1); without this an error ``x_d - x``
    could ask the robot to unwind a full turn that does not exist. Works on a batch
    (``x``: N×8, ``reference``: N×8 or 8, ``jacobian``: N×8×n) as well.
    """
    x = np.asarray(x, dtype=float)
    dots = np.sum(x * reference, axis=-1)
    if x.ndim == 1:
        if dots < 0.0:
            return -x, (None if jacobian is None else -jacobian)
        return x, jacobian
    sign = np.where(dots < 0.0, -1.0, 1.0)
    x = x * sign[:, None]
    if jacobian is not None:
        jacobian = jacobian * sign[:, None, None]
    return x, jacobian


def pose_error(
    x: np.ndarray, x_desired: np.ndarray
) -> tuple[np.ndarray | float, np.ndarray | float]:
    """Translation error [m] and rotation error [rad] between poses (broadcasts).

    Returns ``(‖t_d - t‖, angle(r* r_d))``: the same error as ``‖x_d - x‖`` in units a person
    reads (docs/theory.md §9).
    """
    x = np.asarray(x, dtype=float)
    x_desired = np.asarray(x_desired, dtype=float)
    dt = np.linalg.norm(translation(x_desired) - translation(x), axis=-1)
    rel = qmul(qconj(x[..., :4]), x_desired[..., :4])
    return dt, rotation_angle(rel)
