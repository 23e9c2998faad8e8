"""Property tests of the quaternion / dual-quaternion layer (``dqcontrol.dq.algebra``).

Conventions under test (docs/theory.md §1): ``vec8 = [r_w, r_x, r_y, r_z, d_w, d_x, d_y, d_z]``,
``d = ½ t r``, ``vec8(a b) = H+8(a) vec8(b) = H-8(b) vec8(a)``, ``vec8(x*) = C8 vec8(x)``.
Hypothesis draws are derandomised by the ``ci`` profile (tests/conftest.py); the few numpy
draws are seeded.
"""

from __future__ import annotations

import re

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dqcontrol.dq.algebra import (
    C4,
    C8,
    align_sign,
    dq_conj,
    dq_from_matrix,
    dq_from_rt,
    dq_from_se3,
    dq_from_translation,
    dq_inv,
    dq_is_unit,
    dq_mul,
    dq_norm,
    dq_normalize,
    dq_to_matrix,
    dq_to_se3,
    haminus4,
    haminus8,
    hamiplus4,
    hamiplus8,
    pose_error,
    qconj,
    qfrom_axis_angle,
    qfrom_matrix,
    qmul,
    qto_matrix,
    rotation,
    rotation_angle,
    rotation_axis,
    translation,
)
from dqcontrol.errors import ParameterError

TOL = 1e-12
ONE8 = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])
ONE4 = np.array([1.0, 0, 0, 0])


# --------------------------------------------------------------------------- strategies
def _vectors(n: int, bound: float) -> st.SearchStrategy[np.ndarray]:
    return st.lists(
        st.floats(-bound, bound, allow_nan=False, allow_infinity=False, width=64),
        min_size=n,
        max_size=n,
    ).map(lambda v: np.array(v, dtype=float))


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    if n < 1e-3:  # hypothesis likes the zero vector; any fixed unit vector will do
        return np.eye(v.size)[0].copy()
    return v / n


#: Unit quaternions (both hemispheres: ``w`` of either sign).
unit_quaternions = _vectors(4, 1.0).map(_unit)
#: Translations [m].
translations = _vectors(3, 2.0)
#: Unit dual quaternions from a random rotation and translation.
unit_dqs = st.builds(dq_from_rt, unit_quaternions, translations)
#: Unit axes and angles in [0, π].
unit_axes = _vectors(3, 1.0).map(_unit)
angles = st.floats(0.0, np.pi, allow_nan=False)


def _nonunit_primary(v: np.ndarray) -> np.ndarray:
    v = v.copy()
    if np.linalg.norm(v[:4]) < 0.2:
        v[0] += 1.0
    return v


#: General dual quaternions with a primary part of norm ≥ ~0.2 (invertible, not unit).
general_dqs = _vectors(8, 2.0).map(_nonunit_primary)
general_quaternions = _vectors(4, 2.0)


def assert_close(a, b, tol: float = TOL) -> None:
    np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0.0, atol=tol)


def assert_close_up_to_sign(a, b, tol: float = TOL) -> None:
    a, b = np.asarray(a), np.asarray(b)
    err = min(np.abs(a - b).max(), np.abs(a + b).max())
    assert err <= tol, f"{a} != ±{b} (error {err:.3g})"


# --------------------------------------------------------------------------- products
@given(general_quaternions, general_quaternions, general_quaternions)
def test_quaternion_product_is_associative(a, b, c):
    assert_close(qmul(qmul(a, b), c), qmul(a, qmul(b, c)), 1e-11)


@given(general_dqs, general_dqs, general_dqs)
def test_dq_product_is_associative(a, b, c):
    assert_close(dq_mul(dq_mul(a, b), c), dq_mul(a, dq_mul(b, c)), 1e-11)


@given(general_dqs, general_dqs)
def test_conjugate_of_product_reverses_order(a, b):
    assert_close(dq_conj(dq_mul(a, b)), dq_mul(dq_conj(b), dq_conj(a)))
    assert_close(qconj(qmul(a[:4], b[:4])), qmul(qconj(b[:4]), qconj(a[:4])))


def test_product_is_not_commutative():
    i, j = np.array([0.0, 1, 0, 0]), np.array([0.0, 0, 1, 0])
    assert_close(qmul(i, j), [0, 0, 0, 1])  # i j = k
    assert_close(qmul(j, i), [0, 0, 0, -1])  # j i = -k


@given(unit_dqs, unit_dqs)
def test_unit_norm_is_preserved_by_products(a, b):
    assert_close(dq_norm(a), [1.0, 0.0])
    ab = dq_mul(a, b)
    assert_close(dq_norm(ab), [1.0, 0.0])
    assert dq_is_unit(ab)


@given(general_dqs)
def test_dq_is_unit_rejects_non_unit(x):
    n = dq_norm(x)
    expected = abs(n[0] - 1.0) <= 1e-9 and abs(n[1]) <= 1e-9
    assert dq_is_unit(x) == expected
    assert not dq_is_unit(2.0 * dq_from_rt(ONE4, [0.1, 0.2, 0.3]))


@given(general_dqs)
def test_dq_normalize_gives_unit_with_same_rotation(x):
    u = dq_normalize(x)
    assert dq_is_unit(u, 1e-12)
    assert_close(u[:4], x[:4] / np.linalg.norm(x[:4]))


@given(unit_dqs)
def test_dq_normalize_leaves_unit_dq_unchanged(x):
    assert_close(dq_normalize(x), x)


def test_products_broadcast_over_a_batch():
    rng = np.random.default_rng(11)
    a = rng.normal(size=(5, 8))
    b = rng.normal(size=(5, 8))
    batch = dq_mul(a, b)
    assert batch.shape == (5, 8)
    for i in range(5):
        assert_close(batch[i], dq_mul(a[i], b[i]), 1e-14)  # different summation order


# --------------------------------------------------------------------------- Hamilton operators
@given(general_dqs, general_dqs)
def test_hamilton_operators_8(a, b):
    ab = dq_mul(a, b)
    assert_close(hamiplus8(a) @ b, ab)
    assert_close(haminus8(b) @ a, ab)


@given(general_quaternions, general_quaternions)
def test_hamilton_operators_4(a, b):
    ab = qmul(a, b)
    assert_close(hamiplus4(a) @ b, ab)
    assert_close(haminus4(b) @ a, ab)


def test_hamilton_operators_against_hand_expansion():
    """``H+4(i) = [[0,-1,0,0],[1,0,0,0],[0,0,0,-1],[0,0,1,0]]`` (i·1 = i, i·i = -1, i·j = k)."""
    i = np.array([0.0, 1, 0, 0])
    assert_close(hamiplus4(i), [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 0, -1], [0, 0, 1, 0]], 0)
    # j·i = -k, so H-4(i) maps j to -k; k·i = j
    assert_close(haminus4(i), [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 0, 1], [0, 0, -1, 0]], 0)


@given(general_dqs)
def test_c8_is_the_conjugate(x):
    assert_close(C8 @ x, dq_conj(x), 0.0)
    assert_close(C4 @ x[:4], qconj(x[:4]), 0.0)
    assert_close(dq_conj(dq_conj(x)), x, 0.0)


# --------------------------------------------------------------------------- inverse
@given(unit_dqs)
def test_inverse_of_unit_dq_is_its_conjugate(x):
    inv = dq_inv(x)
    assert_close(inv, dq_conj(x))
    assert_close(dq_mul(inv, x), ONE8)
    assert_close(dq_mul(x, inv), ONE8)


@given(general_dqs)
def test_inverse_of_non_unit_dq(x):
    inv = dq_inv(x)
    assert_close(dq_mul(inv, x), ONE8, 1e-10)
    assert_close(dq_mul(x, inv), ONE8, 1e-10)


# --------------------------------------------------------------------------- conversions
@given(unit_quaternions, translations)
def test_se3_round_trip_from_placement(r, t):
    placement = pin.SE3(qto_matrix(r), t)
    back = dq_to_se3(dq_from_se3(placement))
    assert_close(back.homogeneous, placement.homogeneous)


@given(unit_dqs)
def test_se3_round_trip_from_dq(x):
    y = dq_from_se3(dq_to_se3(x))
    assert y[0] >= 0.0
    assert_close_up_to_sign(y, x)


@given(unit_quaternions, translations)
def test_dq_from_se3_matches_definition(r, t):
    """vec8 of a placement is ``[r, ½ t r]`` with the rotation's ``w ≥ 0``."""
    x = dq_from_se3(pin.SE3(qto_matrix(r), t))
    r_pos = r if r[0] >= 0 else -r
    assert_close_up_to_sign(x[:4], r_pos)
    assert_close(x[4:], 0.5 * qmul(np.concatenate(([0.0], t)), x[:4]))


@given(unit_quaternions, translations)
def test_matrix_round_trip_from_matrix(r, t):
    T = np.eye(4)
    T[:3, :3] = qto_matrix(r)
    T[:3, 3] = t
    assert_close(dq_to_matrix(dq_from_matrix(T)), T)


@given(unit_dqs)
def test_matrix_round_trip_from_dq(x):
    assert_close_up_to_sign(dq_from_matrix(dq_to_matrix(x)), x)


@given(unit_quaternions, translations)
def test_translation_and_rotation_of_dq_from_rt(r, t):
    x = dq_from_rt(r, t)
    assert_close(translation(x), t)
    assert_close(rotation(x), r, 0.0)
    assert_close(translation(-x), t)  # x and -x are the same pose


@given(translations)
def test_dq_from_translation(t):
    x = dq_from_translation(t)
    assert_close(x, dq_from_rt(ONE4, t), 0.0)
    assert_close(dq_to_matrix(x)[:3, 3], t)


@given(unit_quaternions)
def test_qto_matrix_is_a_rotation_matching_pinocchio(r):
    R = qto_matrix(r)
    assert_close(R.T @ R, np.eye(3))
    assert np.linalg.det(R) == pytest.approx(1.0, abs=TOL)
    expected = pin.Quaternion(r[0], r[1], r[2], r[3]).toRotationMatrix()
    assert_close(R, expected)


@given(unit_quaternions)
def test_qfrom_matrix_inverts_qto_matrix(r):
    q = qfrom_matrix(qto_matrix(r))
    assert q[0] >= 0.0
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=TOL)
    assert_close_up_to_sign(q, r)


@given(unit_dqs)
def test_dq_to_matrix_moves_points_like_x_p_x_conj(x):
    """A point p is mapped to ``t + R p``, i.e. ``r p r*`` plus the translation."""
    p = np.array([0.3, -0.2, 0.7])
    rotated = qmul(qmul(x[:4], np.concatenate(([0.0], p))), qconj(x[:4]))[1:]
    T = dq_to_matrix(x)
    assert_close(T[:3, :3] @ p + T[:3, 3], rotated + translation(x))


# --------------------------------------------------------------------------- angle and axis
@given(unit_axes, angles)
def test_rotation_angle_and_axis_against_axis_angle(axis, angle):
    q = qfrom_axis_angle(axis, angle)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=TOL)
    assert rotation_angle(q) == pytest.approx(angle, abs=1e-12)
    assert rotation_angle(-q) == pytest.approx(angle, abs=1e-12)  # x and -x agree
    x = dq_from_rt(q, [0.1, 0.2, 0.3])
    assert rotation_angle(x) == pytest.approx(angle, abs=1e-12)
    if angle > 1e-6:
        assert_close(rotation_axis(q), axis, 1e-9)
        assert_close(rotation_axis(-q), axis, 1e-9)
        assert_close(rotation_axis(x), axis, 1e-9)


def test_rotation_axis_of_identity_is_z():
    assert_close(rotation_axis(ONE4), [0.0, 0.0, 1.0], 0.0)
    assert_close(rotation_axis(ONE8), [0.0, 0.0, 1.0], 0.0)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-9, 1e-7, 1e-4])
def test_rotation_angle_is_exact_near_zero(angle):
    """An ``acos(w)`` formula returns 0 below ~1e-8; ``atan2`` keeps the relative precision."""
    q = qfrom_axis_angle([0.3, -0.5, 0.8], angle)
    assert rotation_angle(q) == pytest.approx(angle, rel=1e-12, abs=1e-300)


@pytest.mark.parametrize("gap", [0.0, 1e-12, 1e-9, 1e-7, 1e-4])
def test_rotation_angle_is_exact_near_pi(gap):
    q = qfrom_axis_angle([0.3, -0.5, 0.8], np.pi - gap)
    assert rotation_angle(q) == pytest.approx(np.pi - gap, abs=2e-15)
    # just past π the same rotation is π - gap the other way round: the angle stays ≤ π
    q2 = qfrom_axis_angle([0.3, -0.5, 0.8], np.pi + gap)
    assert rotation_angle(q2) == pytest.approx(np.pi - gap, abs=2e-15)


def test_rotation_angle_broadcasts():
    qs = np.array([qfrom_axis_angle([1.0, 0, 0], a) for a in (0.1, 0.5, 2.0)])
    assert_close(rotation_angle(qs), [0.1, 0.5, 2.0])


# --------------------------------------------------------------------------- sign alignment
@given(unit_dqs, unit_dqs, st.integers(0, 2**32 - 1))
def test_align_sign_single(x, ref, seed):
    jac = np.random.default_rng(seed).normal(size=(8, 7))
    y, jy = align_sign(x, ref, jac)
    dot = float(np.dot(x, ref))
    assert np.dot(y, ref) >= -1e-15
    # the flip is all-or-nothing and the Jacobian goes with the pose
    sign = 1.0 if np.array_equal(y, x) else -1.0
    if abs(dot) > 1e-12:  # away from the tie, the sign is that of the dot product
        assert sign == np.sign(dot)
    assert_close(y, sign * x, 0.0)
    assert_close(jy, sign * jac, 0.0)
    y2, none = align_sign(x, ref)
    assert none is None
    assert_close(y2, y, 0.0)


def test_align_sign_flips_when_opposite():
    x = dq_from_rt(qfrom_axis_angle([0, 0, 1.0], 0.3), [0.1, 0.2, 0.3])
    jac = np.arange(16.0).reshape(8, 2)
    y, jy = align_sign(x, -x, jac)
    assert_close(y, -x, 0.0)
    assert_close(jy, -jac, 0.0)
    y, jy = align_sign(x, x, jac)
    assert_close(y, x, 0.0)
    assert_close(jy, jac, 0.0)


@pytest.mark.parametrize("per_row_reference", [False, True])
def test_align_sign_batch(per_row_reference):
    rng = np.random.default_rng(2024)
    n_batch = 50
    xs = np.array(
        [dq_from_rt(_unit(rng.normal(size=4)), rng.normal(size=3)) for _ in range(n_batch)]
    )
    ref = xs * np.where(rng.random(n_batch) < 0.5, -1.0, 1.0)[:, None]
    ref = ref + 0.01 * rng.normal(size=ref.shape)
    if not per_row_reference:
        ref = ref[0]
    jacs = rng.normal(size=(n_batch, 8, 7))
    ys, jys = align_sign(xs, ref, jacs)
    dots = np.sum(ys * ref, axis=-1)
    assert (dots >= 0.0).all()
    signs = np.where(np.sum(xs * ref, axis=-1) < 0.0, -1.0, 1.0)
    if per_row_reference:
        assert (signs < 0).any() and (signs > 0).any()  # both branches exercised
    assert_close(ys, xs * signs[:, None], 0.0)
    assert_close(jys, jacs * signs[:, None, None], 0.0)


# --------------------------------------------------------------------------- pose error
def test_pose_error_hand_computed():
    x = ONE8
    xd = dq_from_rt(qfrom_axis_angle([0, 0, 1.0], np.pi / 2), [0.3, 0.4, 0.0])
    dt, angle = pose_error(x, xd)
    assert dt == pytest.approx(0.5, abs=TOL)
    assert angle == pytest.approx(np.pi / 2, abs=TOL)
    # symmetric and insensitive to the sign of either pose
    for a, b in ((xd, x), (-x, xd), (x, -xd)):
        dt2, angle2 = pose_error(a, b)
        assert dt2 == pytest.approx(0.5, abs=TOL)
        assert angle2 == pytest.approx(np.pi / 2, abs=TOL)


def test_pose_error_of_a_relative_motion():
    """``x_d = x ⊗ (rotation θ about an axis, translation u in the x frame)``: the rotation
    error is θ and the translation error is ``|R u|`` = ``|u|``."""
    x = dq_from_rt(qfrom_axis_angle([1.0, 2.0, -0.5], 1.1), [0.5, -0.2, 0.9])
    theta, u = 0.7, np.array([0.03, -0.04, 0.12])
    xd = dq_mul(x, dq_from_rt(qfrom_axis_angle([0.2, 0.1, 1.0], theta), u))
    dt, angle = pose_error(x, xd)
    assert dt == pytest.approx(0.13, abs=TOL)
    assert angle == pytest.approx(theta, abs=TOL)
    assert_close(pose_error(x, x), [0.0, 0.0])
    assert_close(pose_error(x, -x), [0.0, 0.0])


def test_pose_error_broadcasts():
    xs = np.array([dq_from_translation([0.1 * k, 0.0, 0.0]) for k in range(4)])
    dt, angle = pose_error(xs, ONE8)
    assert_close(dt, [0.0, 0.1, 0.2, 0.3])
    assert_close(angle, np.zeros(4))


def test_bad_algebra_arguments():
    with pytest.raises(ParameterError, match="non-zero 3-vector"):
        qfrom_axis_angle([0.0, 0.0, 0.0], 1.0)
    with pytest.raises(ParameterError, match="non-zero 3-vector"):
        qfrom_axis_angle([1.0, 0.0], 1.0)
    with pytest.raises(ParameterError, match="no inverse"):
        dq_inv(np.array([0.0, 0, 0, 0, 1, 0, 0, 0]))
    with pytest.raises(ParameterError, match=re.escape("shape (8,)")):
        dq_to_se3(np.zeros(7))
    with pytest.raises(ParameterError, match=re.escape("shape (3, 3)")):
        qfrom_matrix(np.eye(4))
