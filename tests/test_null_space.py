"""The null-space basis of the levels' held rows, against the SVD's."""

import numpy as np
import pytest

from dqcontrol.controllers.null_space import null_space


@pytest.mark.parametrize(
    ("rows", "cols", "rank"),
    [(60, 80, 60), (3, 8, 2), (20, 20, 10), (10, 5, 5), (12, 30, 7), (1, 4, 1), (5, 9, 0)],
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
