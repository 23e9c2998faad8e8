"""The compiled pose kernels of ``dqcontrol.dq.kernels`` against docs/theory.md §2 written with
the Hamilton operators of ``dqcontrol.dq.algebra`` and against Pinocchio's placement."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from dqcontrol.dq.algebra import dq_from_se3, dq_to_se3
from dqcontrol.dq.kernels import pose_from_xyzquat, pose_jacobian_batch, pose_jacobian_from_xyzquat


def test_pose_kernel_equals_hamilton_operator_form():
    """The compiled pose + Jacobian (dqcontrol.dq.kernels) against docs/theory.md §2 written
    with the Hamilton operators of the algebra module, on random placements and Jacobians,
    half of them with ``r_w < 0`` (the kernel flips to ``r_w ≥ 0``)."""
    from dqcontrol.dq.algebra import haminus4, hamiplus4, qmul

    rng = np.random.default_rng(11)
    vs, j6s = [], []
    for k in range(200):
        r = rng.standard_normal(4)
        r /= np.linalg.norm(r)
        r = np.copysign(r, [1.0, 1.0, 1.0, 1.0 if k % 2 else -1.0])  # x, y, z, w
        t = rng.uniform(-2.0, 2.0, 3)
        j6 = rng.standard_normal((6, 1 + k % 9))
        x, jac = pose_jacobian_from_xyzquat(np.concatenate((t, r)), j6)
        r_wxyz = np.array([r[3], r[0], r[1], r[2]]) * (1.0 if r[3] >= 0.0 else -1.0)
        tq = np.concatenate(([0.0], t))
        x_ref = np.concatenate((r_wxyz, 0.5 * qmul(tq, r_wxyz)))
        hm = haminus4(r_wxyz)[:, 1:4]
        j_r = 0.5 * hm @ j6[3:]
        j_d = 0.5 * (hm @ j6[:3] + hamiplus4(tq) @ j_r)
        np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-15)
        np.testing.assert_allclose(jac, np.vstack((j_r, j_d)), rtol=0, atol=1e-14)
        if j6.shape[1] == 7:
            vs.append(np.concatenate((t, r)))
            j6s.append(j6)
    xs, jacs = pose_jacobian_batch(np.array(vs), np.array(j6s))
    for v, j6, xb, jb in zip(vs, j6s, xs, jacs, strict=True):
        x, jac = pose_jacobian_from_xyzquat(v, j6)
        assert np.array_equal(x, xb) and np.array_equal(jac, jb)


def test_the_pose_alone_is_pinocchios_placement():
    """``pose_from_xyzquat`` of ``SE3ToXYZQUAT(M)`` is ``M`` as a dual quaternion, ``r_w ≥ 0``,
    and the pose ``pose_jacobian_from_xyzquat`` gives."""
    rng = np.random.default_rng(12)
    for _ in range(50):
        r = rng.standard_normal(4)
        rotation = pin.Quaternion(*(r / np.linalg.norm(r))).toRotationMatrix()
        placement = pin.SE3(rotation, rng.uniform(-1.0, 1.0, 3))
        v = pin.SE3ToXYZQUAT(placement)
        x = pose_from_xyzquat(v)
        assert x[0] >= 0.0
        reference = dq_from_se3(placement)
        reference = reference if reference[0] >= 0.0 else -reference
        np.testing.assert_allclose(x, reference, rtol=0, atol=1e-15)
        np.testing.assert_allclose(dq_to_se3(x).homogeneous, placement.homogeneous, atol=1e-14)
        x_with, _ = pose_jacobian_from_xyzquat(v, rng.standard_normal((6, 3)))
        assert np.array_equal(x, x_with)


def test_no_columns_and_no_frames_give_empty_jacobians():
    v = pin.SE3ToXYZQUAT(pin.SE3.Identity())
    x, jac = pose_jacobian_from_xyzquat(v, np.zeros((6, 0)))
    np.testing.assert_array_equal(x, [1.0, 0, 0, 0, 0, 0, 0, 0])
    assert jac.shape == (8, 0)
    xs, jacs = pose_jacobian_batch(np.zeros((0, 7)), np.zeros((0, 6, 4)))
    assert xs.shape == (0, 8) and jacs.shape == (0, 8, 4)
