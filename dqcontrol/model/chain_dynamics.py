"""The mass matrix's diagonal and the generalised gravity of a serial chain of revolute
joints, for a batch of configurations in one compiled pass (docs/theory.md §2).

The dynamics-aware acceleration bound ``a_max_j = (τ_max_j - |g_j(q)|) / M_jj(q)`` reads
two things of the dynamics at each predicted state: the diagonal of the joint-space
inertia ``M`` and the gravity torques ``g``. For a chain in which every joint is a 1-DoF
revolute joint and the child of the one before, both are sums over the bodies the joint
carries. With ``w_j`` the world axis of joint ``j`` and ``o_j`` its origin, and for each body
``k ≥ j`` its mass ``m_k``, centre of mass ``c_k`` and rotational inertia about it ``I_k``
(world axes):

    M_jj = armature_j + Σ_{k≥j} ( w_jᵀ I_k w_j + m_k |(c_k - o_j) × w_j|² )
    g_j  = -w_j · ( Σ_{k≥j} m_k (c_k - o_j) ) × g⃗

(the kinetic energy of the rotation about ``w_j`` alone, and ``∂V/∂q_j`` of the potential
``V = -Σ m_k g⃗ · c_k``). One forward pass places the joints and bodies, one backward pass
accumulates the sums; the gravity's part needs only the suffix sums of ``m_k`` and
``m_k c_k``. This replaces two Pinocchio calls per configuration (its composite rigid
body algorithm for the whole ``M``, and its gravity), and agrees with them to rounding
(checked when the model is built, and in the tests).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from dqcontrol._compiled import compiled
from dqcontrol.model.chain_batch import revolute_axis

__all__ = ["ChainDynamics", "acceleration_bounds"]


class ChainDynamics:
    """``diag M(q)`` and ``g(q)`` of a serial chain of revolute joints.

    Build with :meth:`build` (``None`` when the model is not such a chain); call
    :meth:`diagonal_and_gravity` with a checked ``(N, n)`` array of configurations.
    """

    def __init__(
        self,
        placements: np.ndarray,
        axes: np.ndarray,
        bodies: np.ndarray,
        inertias: np.ndarray,
        armature: np.ndarray,
        gravity: np.ndarray,
    ) -> None:
        self._placements = placements  # (n, 3, 4): each joint's [R | p] in its parent's frame
        self._axes = axes  # (n, 3): unit axes in the joints' own frames
        self._bodies = bodies  # (n, 4): mass [kg] and centre of mass [m] in the joint's frame
        self._inertias = inertias  # (n, 3, 3): rotational inertia about the centre of mass
        self._armature = armature  # (n,) [kg·m²], added to the diagonal
        self._gravity = gravity  # (3,) [m/s²], world axes

    @classmethod
    def build(cls, model: pin.Model) -> ChainDynamics | None:
        """Tables for ``model``, or ``None`` if it is not a serial chain of 1-DoF revolute
        joints about fixed axes (each joint the child of the one before, ``nq == nv``)."""
        n = int(model.nq)
        if n == 0 or model.nv != n or model.njoints != n + 1:
            return None
        placements, axes = np.empty((n, 3, 4)), np.empty((n, 3))
        bodies, inertias = np.empty((n, 4)), np.empty((n, 3, 3))
        for j in range(1, n + 1):
            axis = revolute_axis(model.joints[j])
            if axis is None or model.joints[j].nq != 1 or model.parents[j] != j - 1:
                return None
            placement, body = model.jointPlacements[j], model.inertias[j]
            placements[j - 1, :, :3] = placement.rotation
            placements[j - 1, :, 3] = placement.translation
            axes[j - 1] = axis
            bodies[j - 1, 0] = body.mass
            bodies[j - 1, 1:] = body.lever
            inertias[j - 1] = body.inertia
        armature = np.array(model.armature, dtype=float)
        return cls(placements, axes, bodies, inertias, armature, np.array(model.gravity.linear))

    def diagonal_and_gravity(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(diag M(q), g(q))`` at each row of ``qs``: two ``(N, n)`` arrays
        [kg·m², N·m]."""
        diag, g = np.empty(qs.shape), np.empty(qs.shape)
        diagonal_gravity_into(
            qs, self._placements, self._axes, self._bodies, self._inertias, self._armature,
            self._gravity, diag, g,
        )  # fmt: skip
        return diag, g


@compiled
def _joint_frame(rot, origin, placement, axis, angle):
    """The frame of a joint turned by ``angle`` after its parent's ``(rot, origin)``
    (``rot`` row by row, nine numbers): ``R P_R Rot(axis, angle)``, ``o + R P_p``, and the
    joint's world axis ``R P_R axis``."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
    o = (
        origin[0] + r00 * placement[0, 3] + r01 * placement[1, 3] + r02 * placement[2, 3],
        origin[1] + r10 * placement[0, 3] + r11 * placement[1, 3] + r12 * placement[2, 3],
        origin[2] + r20 * placement[0, 3] + r21 * placement[1, 3] + r22 * placement[2, 3],
    )
    b = _times(rot, placement)
    x, y, z = axis[0], axis[1], axis[2]
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    turn = (  # Rodrigues' rotation about the unit axis
        c + x * x * t, x * y * t - z * s, x * z * t + y * s,
        y * x * t + z * s, c + y * y * t, y * z * t - x * s,
        z * x * t - y * s, z * y * t + x * s, c + z * z * t,
    )  # fmt: skip
    w = (
        b[0] * x + b[1] * y + b[2] * z,
        b[3] * x + b[4] * y + b[5] * z,
        b[6] * x + b[7] * y + b[8] * z,
    )
    return _product(b, turn), o, w


@compiled
def _times(rot, m):
    """``R M`` for ``R`` given row by row (nine numbers) and ``M`` ``(3, ≥3)``: nine numbers."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
    return (
        r00 * m[0, 0] + r01 * m[1, 0] + r02 * m[2, 0],
        r00 * m[0, 1] + r01 * m[1, 1] + r02 * m[2, 1],
        r00 * m[0, 2] + r01 * m[1, 2] + r02 * m[2, 2],
        r10 * m[0, 0] + r11 * m[1, 0] + r12 * m[2, 0],
        r10 * m[0, 1] + r11 * m[1, 1] + r12 * m[2, 1],
        r10 * m[0, 2] + r11 * m[1, 2] + r12 * m[2, 2],
        r20 * m[0, 0] + r21 * m[1, 0] + r22 * m[2, 0],
        r20 * m[0, 1] + r21 * m[1, 1] + r22 * m[2, 1],
        r20 * m[0, 2] + r21 * m[1, 2] + r22 * m[2, 2],
    )


@compiled
def _product(a, b):
    """``A B`` of two rotations given row by row (nine numbers each): nine numbers."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = a
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = b
    return (
        a00 * b00 + a01 * b10 + a02 * b20,
        a00 * b01 + a01 * b11 + a02 * b21,
        a00 * b02 + a01 * b12 + a02 * b22,
        a10 * b00 + a11 * b10 + a12 * b20,
        a10 * b01 + a11 * b11 + a12 * b21,
        a10 * b02 + a11 * b12 + a12 * b22,
        a20 * b00 + a21 * b10 + a22 * b20,
        a20 * b01 + a21 * b11 + a22 * b21,
        a20 * b02 + a21 * b12 + a22 * b22,
    )


@compiled
def _body_terms(rot, origin, bodies, inertias, j, coms, world_inertias) -> None:
    """Body ``j``'s centre of mass ``o + R lever`` and inertia ``R I Rᵀ`` in world axes,
    written to ``coms[j]`` and ``world_inertias[j]``."""
    for r in range(3):
        coms[j, r] = (
            origin[r]
            + rot[3 * r] * bodies[j, 1]
            + rot[3 * r + 1] * bodies[j, 2]
            + (rot[3 * r + 2] * bodies[j, 3])
        )
    ri = _times(rot, inertias[j])  # R I, then (R I) Rᵀ
    for r in range(3):
        for k in range(3):
            world_inertias[j, r, k] = (
                ri[3 * r] * rot[3 * k]
                + ri[3 * r + 1] * rot[3 * k + 1]
                + ri[3 * r + 2] * rot[3 * k + 2]
            )


@compiled
def _diagonal_entry(j, w, o, coms, world_inertias, bodies, armature) -> float:
    """``M_jj``: the armature and, for each body ``k ≥ j``, ``w_jᵀ I_k w_j`` and
    ``m_k |(c_k - o_j) × w_j|²`` (``w``, ``o``: joint ``j``'s axis and origin)."""
    w0, w1, w2 = w
    total = armature[j]
    for k in range(j, coms.shape[0]):
        d0, d1, d2 = coms[k, 0] - o[0], coms[k, 1] - o[1], coms[k, 2] - o[2]
        e0, e1, e2 = d1 * w2 - d2 * w1, d2 * w0 - d0 * w2, d0 * w1 - d1 * w0
        spin = 0.0
        for r in range(3):
            i_r = world_inertias[k, r]
            spin += w[r] * (i_r[0] * w0 + i_r[1] * w1 + i_r[2] * w2)
        total += spin + bodies[k, 0] * (e0 * e0 + e1 * e1 + e2 * e2)
    return total


@compiled
def diagonal_gravity_into(qs, placements, axes, bodies, inertias, armature, gravity, diag, g):
    """``diag[i] = diag M(qs[i])`` and ``g[i] = g(qs[i])`` (module docstring)."""
    count, n = qs.shape
    frames = np.empty((n, 6))  # each joint's world axis and origin
    coms, world_inertias = np.empty((n, 3)), np.empty((n, 3, 3))
    for i in range(count):
        rot = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)  # the universe's frame
        o = (0.0, 0.0, 0.0)
        for j in range(n):
            rot, o, w = _joint_frame(rot, o, placements[j], axes[j], qs[i, j])
            frames[j, 0], frames[j, 1], frames[j, 2] = w
            frames[j, 3], frames[j, 4], frames[j, 5] = o
            _body_terms(rot, o, bodies, inertias, j, coms, world_inertias)
        mass, m0, m1, m2 = 0.0, 0.0, 0.0, 0.0  # suffix sums of m_k and of m_k c_k
        for j in range(n - 1, -1, -1):
            m_j = bodies[j, 0]
            mass += m_j
            m0, m1, m2 = m0 + m_j * coms[j, 0], m1 + m_j * coms[j, 1], m2 + m_j * coms[j, 2]
            w = (frames[j, 0], frames[j, 1], frames[j, 2])
            o = (frames[j, 3], frames[j, 4], frames[j, 5])
            diag[i, j] = _diagonal_entry(j, w, o, coms, world_inertias, bodies, armature)
            f0, f1, f2 = m0 - mass * o[0], m1 - mass * o[1], m2 - mass * o[2]
            t0 = f1 * gravity[2] - f2 * gravity[1]
            t1 = f2 * gravity[0] - f0 * gravity[2]
            t2 = f0 * gravity[1] - f1 * gravity[0]
            g[i, j] = -(w[0] * t0 + w[1] * t1 + w[2] * t2)


@compiled
def acceleration_bounds(diag, g, effort_fraction, effort_max, floor, cap):
    """``clip((effort_fraction τ_max - |g|) / diag, floor, cap)`` entry by entry, as numpy
    computes it (a NaN stays NaN), and whether every ``diag`` entry is positive (where one
    is not, its bound is NaN)."""
    out = np.empty(diag.shape)
    positive = True
    for i in range(diag.shape[0]):
        for j in range(diag.shape[1]):
            d = diag[i, j]
            if not d > 0.0:
                positive = False
                out[i, j] = np.nan
                continue
            v = (effort_fraction * effort_max[j] - abs(g[i, j])) / d
            if v < floor:
                v = floor
            if v > cap:
                v = cap
            out[i, j] = v
    return out, positive
