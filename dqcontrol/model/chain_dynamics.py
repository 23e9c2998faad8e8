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
def _place(
    rotation, origin, placement, axis, angle, turn, before, rotation_out, origin_out, axis_out
) -> None:
    """The frame of a joint turned by ``angle``: ``R_out = R P_R Rot(axis, angle)``,
    ``o_out = o + R P_p``, and its world axis ``R P_R axis`` (``turn``, ``before``:
    ``(3, 3)`` scratch)."""
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = axis[0], axis[1], axis[2]
    t = 1.0 - c
    turn[0, 0], turn[0, 1], turn[0, 2] = c + x * x * t, x * y * t - z * s, x * z * t + y * s
    turn[1, 0], turn[1, 1], turn[1, 2] = y * x * t + z * s, c + y * y * t, y * z * t - x * s
    turn[2, 0], turn[2, 1], turn[2, 2] = z * x * t - y * s, z * y * t + x * s, c + z * z * t
    for r in range(3):
        origin_out[r] = origin[r]
        for k in range(3):
            origin_out[r] += rotation[r, k] * placement[k, 3]
            before[r, k] = (
                rotation[r, 0] * placement[0, k]
                + rotation[r, 1] * placement[1, k]
                + rotation[r, 2] * placement[2, k]
            )
        axis_out[r] = before[r, 0] * x + before[r, 1] * y + before[r, 2] * z
    for r in range(3):
        for k in range(3):
            rotation_out[r, k] = (
                before[r, 0] * turn[0, k] + before[r, 1] * turn[1, k] + before[r, 2] * turn[2, k]
            )


@compiled
def _body_terms(rotation, origin, body, inertia, com_out, inertia_out) -> None:
    """A body's centre of mass ``o + R lever`` and inertia ``R I Rᵀ`` in world axes."""
    for r in range(3):
        com_out[r] = origin[r]
        for k in range(3):
            com_out[r] += rotation[r, k] * body[1 + k]
    for r in range(3):  # (R I) Rᵀ, a row of R I at a time
        ri0 = rotation[r, 0] * inertia[0, 0] + rotation[r, 1] * inertia[1, 0]
        ri1 = rotation[r, 0] * inertia[0, 1] + rotation[r, 1] * inertia[1, 1]
        ri2 = rotation[r, 0] * inertia[0, 2] + rotation[r, 1] * inertia[1, 2]
        ri0 += rotation[r, 2] * inertia[2, 0]
        ri1 += rotation[r, 2] * inertia[2, 1]
        ri2 += rotation[r, 2] * inertia[2, 2]
        for k in range(3):
            inertia_out[r, k] = ri0 * rotation[k, 0] + ri1 * rotation[k, 1] + ri2 * rotation[k, 2]


@compiled
def diagonal_gravity_into(qs, placements, axes, bodies, inertias, armature, gravity, diag, g):
    """``diag[i] = diag M(qs[i])`` and ``g[i] = g(qs[i])`` (module docstring)."""
    count, n = qs.shape
    rotations, origins = np.zeros((n + 1, 3, 3)), np.zeros((n + 1, 3))
    for r in range(3):
        rotations[0, r, r] = 1.0  # the universe's frame
    world_axes, coms, world_inertias = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3, 3))
    turn, before, moment = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    for i in range(count):
        for j in range(n):
            _place(rotations[j], origins[j], placements[j], axes[j], qs[i, j], turn, before,
                   rotations[j + 1], origins[j + 1], world_axes[j])  # fmt: skip
            _body_terms(rotations[j + 1], origins[j + 1], bodies[j], inertias[j],
                        coms[j], world_inertias[j])  # fmt: skip
        mass = 0.0  # suffix sums of m_k and of m_k c_k
        moment[:] = 0.0
        for j in range(n - 1, -1, -1):
            m_j = bodies[j, 0]
            mass += m_j
            for r in range(3):
                moment[r] += m_j * coms[j, r]
            w, o = world_axes[j], origins[j + 1]
            total = armature[j]
            for k in range(j, n):
                d0, d1, d2 = coms[k, 0] - o[0], coms[k, 1] - o[1], coms[k, 2] - o[2]
                e0, e1, e2 = d1 * w[2] - d2 * w[1], d2 * w[0] - d0 * w[2], d0 * w[1] - d1 * w[0]
                spin = 0.0
                for r in range(3):
                    for c in range(3):
                        spin += w[r] * world_inertias[k, r, c] * w[c]
                total += spin + bodies[k, 0] * (e0 * e0 + e1 * e1 + e2 * e2)
            diag[i, j] = total
            f0, f1, f2 = moment[0] - mass * o[0], moment[1] - mass * o[1], moment[2] - mass * o[2]
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
