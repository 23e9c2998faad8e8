"""Batched pose and pose Jacobian of a serial chain of revolute joints, in closed form.

For a chain of revolute joints the end-effector pose is a product of constant dual
quaternions and joint rotations ``cos(θ_j/2) + sin(θ_j/2) a_j``, so ``vec8(x)`` is a
multilinear polynomial in the pairs ``(cos(θ_j/2), sin(θ_j/2))``; its partial derivatives
are too (``∂/∂θ_j`` swaps the pair to ``½(-sin, cos)``). The pose and the whole pose
Jacobian are therefore one constant matrix ``T`` times a basis of ``2^m`` products, with
``m`` the joints that move the end-effector.

The basis is built from two groups of joints (the first half ``A`` and the rest ``B``): in
each group the products of half-angle cosines and sines are written as cosines and sines of
signed sums of half-angles (product-to-sum), ``2^(g-1)`` phases per group of ``g`` joints.
A batch of N configurations then costs a fixed handful of calls (numpy's products and sine,
two compiled loops), independent of N and of the number of joints::

    phases = qs · E + offsets          (one matrix product, one addition)
    v      = sin(phases)               ([cos, sin] of every phase of both groups)
    k      = v_A ⊗ v_B                 (2^m products per configuration)
    out    = k · T                     ([vec8(x), J] for every configuration)

followed by the sign convention ``r_w ≥ 0`` (docs/theory.md §1) applied to each row. The size
of ``T`` is ``2^m × 8(n+1)``, so this only pays for short chains (``MAX_JOINTS``); longer
ones and any other joint type stay with Pinocchio.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from dqcontrol._compiled import compiled
from dqcontrol.dq.algebra import dq_from_se3, dq_mul

__all__ = ["MAX_JOINTS", "ChainBatch", "revolute_axis"]

#: Longest chain handled in closed form: ``T`` has ``2^m`` rows, and past 8 joints its
#: product costs more than the per-configuration Pinocchio calls it replaces.
MAX_JOINTS = 8

_AXES = {
    "JointModelRX": (1.0, 0.0, 0.0),
    "JointModelRY": (0.0, 1.0, 0.0),
    "JointModelRZ": (0.0, 0.0, 1.0),
}


def revolute_axis(joint) -> np.ndarray | None:
    """Unit axis of a 1-DoF revolute joint in its own frame, ``None`` for any other joint."""
    name = joint.shortname()
    if name in _AXES:
        return np.array(_AXES[name])
    if name == "JointModelRevoluteUnaligned":
        axis = np.array(joint.extract().axis, dtype=float)
        return axis / np.linalg.norm(axis)
    return None


def _fourier(count: int) -> tuple[np.ndarray, np.ndarray]:
    """Product-to-sum map of a group of ``count`` joints.

    Returns ``signs`` (``F × count``, entries ±1, ``F = max(1, 2^(count-1))`` phases
    ``φ_k = Σ_j signs[k, j] θ_j / 2``) and ``M`` (``2^count × 2F``) such that the products
    ``g_b = Π_j (cos if b_j = 0 else sin)(θ_j/2)`` (``b`` read as a binary number, first
    joint most significant) equal ``M @ [cos φ_1..F, sin φ_1..F]``. With no joint the only
    product is the constant 1 = ``cos 0``.
    """
    if count == 0:
        return np.zeros((1, 0)), np.array([[1.0, 0.0]])
    # cos = (e^{iθ} + e^{-iθ})/2, sin = (e^{iθ} - e^{-iθ})/(2i): rows b_j, columns ε_j = +, -
    w1 = np.array([[0.5, 0.5], [-0.5j, 0.5j]])
    w = np.ones((1, 1), dtype=complex)
    for _ in range(count):
        w = np.kron(w, w1)
    half = 2 ** (count - 1)
    # ε with ε_1 = + are the first half; the term of -ε is the complex conjugate, so
    # W e^{iφ} + conj(W) e^{-iφ} = 2 Re(W) cos φ - 2 Im(W) sin φ
    m = np.concatenate((2.0 * w[:, :half].real, -2.0 * w[:, :half].imag), axis=1)
    bits = (np.arange(half)[:, None] >> np.arange(count - 1, -1, -1)[None, :]) & 1
    signs = 1.0 - 2.0 * bits
    return signs, m


class ChainBatch:
    """Closed-form batched ``[vec8(x), J]`` of a frame carried by a chain of revolute joints.

    Build with :meth:`build` (``None`` when the model is not such a chain); call with a
    checked ``(N, n)`` array of configurations.
    """

    def __init__(self, nq: int, e: np.ndarray, offsets: np.ndarray, size_a: int, t: np.ndarray):
        self.nq = nq
        self._e = e
        self._offsets = offsets
        self._size_a = size_a
        self._t = t
        self._t_pose = np.ascontiguousarray(t[:, :8])  # the pose's columns alone
        self._products = t.shape[0]

    @classmethod
    def build(cls, model: pin.Model, frame_id: int) -> ChainBatch | None:
        """Tables for ``model``'s frame ``frame_id``, or ``None`` if it is not supported.

        Supported: every joint between the root and the frame is a 1-DoF revolute joint
        about a fixed axis (``RX/RY/RZ/RevoluteUnaligned``), with at most
        :data:`MAX_JOINTS` of them; joints off that path only give zero Jacobian columns.
        The joint placements, axes and the frame placement are read once, here.
        """
        frame = model.frames[frame_id]
        found = _revolute_chain(model, int(frame.parentJoint))
        if found is None:
            return None
        chain, axes = found
        columns = [int(model.joints[j].idx_q) for j in chain]
        coeffs = _chain_coefficients(model, chain, axes, frame.placement)
        n = int(model.nq)
        flat = _pose_jacobian_coefficients(coeffs, columns, n)

        m = len(chain)
        m_a = m // 2
        signs_a, map_a = _fourier(m_a)
        signs_b, map_b = _fourier(m - m_a)
        size_a, size_b = map_a.shape[1], map_b.shape[1]
        flat = flat.reshape(2**m_a, 2 ** (m - m_a), -1)
        t = np.einsum("abo,ak,bl->klo", flat, map_a, map_b).reshape(size_a * size_b, -1)
        e, offsets = _phase_map(n, (signs_a, columns[:m_a]), (signs_b, columns[m_a:]))
        return cls(n, e, offsets, size_a, np.ascontiguousarray(t))

    def __call__(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(N, 8)`` poses and ``(N, 8, n)`` pose Jacobians of checked configurations."""
        out = self._rows(qs, self._t)
        return out[:, :8], out[:, 8:].reshape(qs.shape[0], 8, self.nq)

    def poses(self, qs: np.ndarray) -> np.ndarray:
        """``(N, 8)`` poses of checked configurations, without the Jacobians (the first
        eight columns of ``T``; ``r_w ≥ 0``)."""
        return self._rows(qs, self._t_pose)

    def _rows(self, qs: np.ndarray, t: np.ndarray) -> np.ndarray:
        """``k · t`` for the products ``k`` of the configurations ``qs`` (module docstring),
        each row's sign set by ``r_w ≥ 0`` (the Jacobian's row flipped with ``x``)."""
        v = qs.dot(self._e)
        v += self._offsets
        np.sin(v, out=v)
        k = np.empty((qs.shape[0], self._products))
        outer_rows_into(v, self._size_a, k)
        out = k.dot(t)
        positive_scalar_rows(out)
        return out


@compiled
def outer_rows_into(v: np.ndarray, split: int, out: np.ndarray) -> None:
    """``out[i] = (v[i, :split] ⊗ v[i, split:]).ravel()`` for every row ``i``."""
    rest = v.shape[1] - split
    for i in range(v.shape[0]):
        for a in range(split):
            va = v[i, a]
            for b in range(rest):
                out[i, a * rest + b] = va * v[i, split + b]


@compiled
def positive_scalar_rows(out: np.ndarray) -> None:
    """Multiply each row of ``out`` in place by ``copysign(1, its first entry)``."""
    for i in range(out.shape[0]):
        sign = math.copysign(1.0, out[i, 0])
        for k in range(out.shape[1]):
            out[i, k] *= sign


def _revolute_chain(model: pin.Model, parent: int) -> tuple[list[int], list[np.ndarray]] | None:
    """The joints from the root to joint ``parent`` and their axes, if :meth:`ChainBatch.build`
    supports them.

    Returns:
        The joint indices (root first) and each joint's unit axis in its own frame, or
        ``None`` when the chain is empty or longer than :data:`MAX_JOINTS`, a joint is not a
        1-DoF revolute joint about a fixed axis, or the model's ``nq`` differs from ``nv``.
    """
    chain = [int(j) for j in model.supports[parent]][1:]
    if not 0 < len(chain) <= MAX_JOINTS or model.nq != model.nv:
        return None
    axes = []
    for j in chain:
        axis = revolute_axis(model.joints[j])
        if axis is None or model.joints[j].nq != 1:
            return None
        axes.append(axis)
    return chain, axes


def _chain_coefficients(
    model: pin.Model, chain: list[int], axes: list[np.ndarray], placement: pin.SE3
) -> np.ndarray:
    """The pose's coefficients over the products of half-angle cosines and sines.

    Row ``b`` (``b`` a binary number over the chain, first joint most significant) is
    ``vec8`` of ``P_1 u_1 P_2 u_2 … u_m P_ee``, with ``P_j`` the joint placements,
    ``P_ee = placement`` that of the frame, and ``u_j = 1`` (``b_j = 0``) or the pure
    quaternion of the axis ``a_j`` (``b_j = 1``). Shape ``(2^m, 8)``.
    """
    coeffs = np.zeros((1, 8))
    coeffs[0, 0] = 1.0
    for j, axis in zip(chain, axes, strict=True):
        coeffs = dq_mul(coeffs, dq_from_se3(model.jointPlacements[j]))
        pure = np.zeros(8)
        pure[1:4] = axis
        coeffs = np.stack((coeffs, dq_mul(coeffs, pure)), axis=1).reshape(-1, 8)
    return dq_mul(coeffs, dq_from_se3(placement))


def _pose_jacobian_coefficients(coeffs: np.ndarray, columns: list[int], n: int) -> np.ndarray:
    """The coefficients of ``[vec8(x), J]`` over the same products as ``coeffs``.

    Args:
        coeffs: the pose's coefficients (:func:`_chain_coefficients`), shape ``(2^m, 8)``.
        columns: the configuration index of each joint of the chain.
        n: the model's number of configuration variables.

    Returns:
        Shape ``(2^m, 8 (n + 1))``: the columns of ``vec8(x)`` (8), then ``J`` row-major
        (``8 × n``; zero in the columns of joints off the chain).
    """
    m = len(columns)
    tensor = coeffs.reshape((2,) * m + (8,))
    # ∂/∂θ_j maps the pair (cos, sin)(θ_j/2) to ½(-sin, cos): the coefficient of a
    # product with b_j = 0 becomes ½ C[b_j = 1], with b_j = 1 it becomes -½ C[b_j = 0]
    outputs = np.zeros((2**m, 8, n + 1))
    outputs[:, :, 0] = coeffs
    for p, col in enumerate(columns):
        moved = np.moveaxis(tensor, p, 0)
        deriv = np.stack((0.5 * moved[1], -0.5 * moved[0]))
        outputs[:, :, 1 + col] = np.moveaxis(deriv, 0, p).reshape(2**m, 8)
    return np.concatenate((outputs[:, :, 0], outputs[:, :, 1:].reshape(2**m, 8 * n)), axis=1)


def _phase_map(
    n: int, group_a: tuple[np.ndarray, list[int]], group_b: tuple[np.ndarray, list[int]]
) -> tuple[np.ndarray, np.ndarray]:
    """The matrix ``E`` and the offsets that map configurations to the phases of both groups.

    Args:
        n: the model's number of configuration variables.
        group_a: the signs of the first group (:func:`_fourier`) and its joints'
            configuration indices.
        group_b: the same for the second group.

    Returns:
        ``E`` (``n × P``) and the offsets (``P``) such that ``sin(q · E + offsets)`` is
        ``[cos φ_A, sin φ_A, cos φ_B, sin φ_B]``: each group's phases twice, the first copy
        offset by π/2 (``cos = sin(· + π/2)``).
    """
    size_a, size_b = 2 * group_a[0].shape[0], 2 * group_b[0].shape[0]
    e = np.zeros((n, size_a + size_b))
    for (signs, group), start in ((group_a, 0), (group_b, size_a)):
        phases = signs.shape[0]
        for k, col in enumerate(group):
            e[col, start : start + phases] = 0.5 * signs[:, k]
            e[col, start + phases : start + 2 * phases] = 0.5 * signs[:, k]
    offsets = np.zeros(size_a + size_b)
    offsets[: size_a // 2] = 0.5 * np.pi
    offsets[size_a : size_a + size_b // 2] = 0.5 * np.pi
    return e, offsets
