"""The null-space basis of the levels' held rows, against the SVD's."""

import numpy as np
import pytest
from scipy.linalg import lapack

from dqcontrol.controllers.linalg import null_space as null_space_module  # the module
from dqcontrol.controllers.linalg.null_space import null_space


@pytest.mark.parametrize(
    ("rows", "cols", "rank"),
    [
        (60, 80, 60),
        (3, 8, 2),
        (20, 20, 10),
        (10, 5, 5),
        (12, 30, 7),
        (1, 4, 1),
        (5, 9, 0),
        (70, 70, 40),
    ],
)
@pytest.mark.parametrize("seed", range(3))
def test_an_orthonormal_basis_of_the_null_space(rows, cols, rank, seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(rows, rank)) @ rng.normal(size=(rank, cols))
    basis = null_space(a)
    expected = cols - np.linalg.matrix_rank(a)
    assert basis.shape == (cols, expected)
    assert np.allclose(basis.T @ basis, np.eye(expected), atol=1e-12)
    assert np.max(np.abs(a @ basis), initial=0.0) <= 1e-12 * max(1.0, np.abs(a).max())
    # the same space as the SVD's: the projector onto it agrees
    _, sv, vt = np.linalg.svd(a)
    tail = vt[np.count_nonzero(sv > 1e-10 * sv[0]) if sv.size and sv[0] > 0 else 0 :]
    assert np.allclose(basis @ basis.T, tail.T @ tail, atol=1e-10)


def test_no_rows_leave_every_direction_free():
    assert np.array_equal(null_space(np.zeros((0, 4))), np.eye(4))


def test_a_row_repeated_counts_once():
    row = np.array([[1.0, 2.0, 3.0]])
    basis = null_space(np.vstack([row, 2.0 * row, -row]))
    assert basis.shape == (3, 2)
    assert np.allclose(row @ basis, 0.0, atol=1e-14)


def _profile_rows(rng, blocks, rows_per_block, block_size, rank_lost=0):
    """Rows of block ``i`` reaching the variables of blocks ``0 … i`` (a predictive path
    level's shape), some entries zero; the last ``rank_lost`` rows repeat earlier ones."""
    n = blocks * block_size
    a = np.zeros((blocks * rows_per_block, n))
    for i in range(blocks):
        reach = (i + 1) * block_size
        part = rng.normal(size=(rows_per_block, reach))
        part[rng.random(size=part.shape) < 0.2] = 0.0
        a[i * rows_per_block : (i + 1) * rows_per_block, :reach] = part
    for k in range(rank_lost):
        a[-1 - k] = 2.0 * a[k]
    return a


@pytest.mark.parametrize(
    ("blocks", "rows_per_block", "block_size"), [(10, 6, 8), (5, 2, 4), (8, 3, 6)]
)
@pytest.mark.parametrize("seed", range(3))
def test_the_profile_qr_gives_lapacks_basis(blocks, rows_per_block, block_size, seed):
    rng = np.random.default_rng(seed)
    a = _profile_rows(rng, blocks, rows_per_block, block_size)
    outcome, basis = null_space_module._profile_complement(np.ascontiguousarray(a.T))
    assert outcome == null_space_module._DONE
    # the same reflectors as LAPACK's unpivoted QR: the same basis, column by column
    reference = null_space_module._lapack_complement(a)
    assert reference is not None
    assert np.allclose(basis, reference, rtol=0, atol=1e-12)
    assert np.array_equal(null_space(a), basis)
    assert np.allclose(basis.T @ basis, np.eye(basis.shape[1]), atol=1e-12)
    assert np.max(np.abs(a @ basis)) <= 1e-12 * np.abs(a).max()


def test_dependent_profile_rows_are_left_to_the_pivoted_qr():
    a = _profile_rows(np.random.default_rng(7), 10, 6, 8, rank_lost=2)
    outcome, _ = null_space_module._profile_complement(np.ascontiguousarray(a.T))
    assert outcome == null_space_module._DEPENDENT
    basis = null_space(a)
    assert basis.shape == (80, 22)
    assert np.max(np.abs(a @ basis)) <= 1e-12 * np.abs(a).max()


def test_dense_rows_are_left_to_lapack():
    a = np.random.default_rng(3).normal(size=(12, 20))
    outcome, _ = null_space_module._profile_complement(np.ascontiguousarray(a.T))
    assert outcome == null_space_module._DENSE


@pytest.mark.parametrize(
    ("rows", "cols", "rank"), [(20, 20, 10), (3, 8, 2), (12, 30, 7), (9, 4, 4)]
)
@pytest.mark.parametrize("seed", range(3))
def test_the_compiled_pivoted_qr_gives_lapacks_basis(rows, cols, rank, seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(rows, rank)) @ rng.normal(size=(rank, cols))
    basis = null_space_module._pivoted(a)
    assert basis.shape == (cols, cols - rank)
    # LAPACK's pivoted QR, Q from its first rank reflectors: the same basis, column by column
    qr, _, tau, _, _ = lapack.dgeqp3(np.array(a.T, order="F"))
    reflectors = np.zeros((cols, cols), order="F")
    reflectors[:, :rank] = qr[:, :rank]
    q, _, _ = lapack.dorgqr(reflectors, tau[:rank])
    assert np.allclose(basis, q[:, rank:], rtol=0, atol=1e-10)
    assert np.allclose(null_space_module._lapack_pivoted(a), basis, rtol=0, atol=1e-10)
