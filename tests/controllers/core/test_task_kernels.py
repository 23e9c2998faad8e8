"""The compiled task kernels of :mod:`dqcontrol.controllers.core.task_kernels` against numpy
computations of the same formulas (docs/theory.md §4)."""

from __future__ import annotations

import numpy as np
import pytest


def test_compiled_cost_equals_numpy_blocks():
    """``qp_cost.add_task_grams`` (after ``align_signs``) against the plain numpy cost of
    docs/theory.md §4 for p instants (flips where ``x_i · x_d,i < 0``, stall damping on the qd
    diagonal), and ``scatter_symmetric`` against fancy indexing."""
    from dqcontrol.controllers.core.task_kernels import (
        add_task_grams,
        align_signs,
        scatter_symmetric,
    )

    rng = np.random.default_rng(5)
    p, n = 10, 7
    m = n + 1
    xs = rng.standard_normal((p, 8))
    jacs = rng.standard_normal((p, 8, n))
    xd = rng.standard_normal((p, 8))
    dxd = rng.standard_normal((p, 8))
    gain, weight, stall = 10.0, 2.5, 1e-3
    diag = np.zeros((p, m, m))
    diag[:, np.arange(n), np.arange(n)] = 1e-4
    diag[:, n, n] = 1e-2
    rows, cols = np.triu_indices(m)
    sign = np.where((xs * xd).sum(axis=1) < 0.0, -1.0, 1.0)
    assert (sign < 0).any() and (sign > 0).any()
    g = np.concatenate(
        (jacs * sign[:, None, None], (gain * (xs * sign[:, None] - xd) - dxd)[:, :, None]), axis=2
    )
    blocks = weight * np.matmul(g.transpose(0, 2, 1), g) + diag
    blocks[:, np.arange(n), np.arange(n)] += stall
    expected = 2.0 * blocks
    xs_in, jacs_in = xs.copy(), jacs.copy()
    align_signs(xs_in, jacs_in, xd)
    got = 2.0 * diag
    add_task_grams(xs_in, jacs_in, xd, dxd, gain, 2.0 * weight, got)
    got[:, np.arange(n), np.arange(n)] += 2.0 * stall
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(got, got.transpose(0, 2, 1))  # exactly symmetric
    np.testing.assert_array_equal(xs_in, xs * sign[:, None])  # flipped in place
    np.testing.assert_array_equal(jacs_in, jacs * sign[:, None, None])

    values = got[0][rows, cols]
    h = np.zeros((m, m))
    scatter_symmetric(h, rows.astype(np.int64), cols.astype(np.int64), values)
    ref = np.zeros((m, m))
    ref[rows, cols] = values
    ref[cols, rows] = values
    np.testing.assert_array_equal(h, ref)


def test_gram_and_task_matrices_are_numpys():
    """``gram`` is ``Gᵀ G`` (exactly symmetric) and ``task_matrices`` stacks
    ``[J_i, K (x_i - x_d,i) - dx_d,i]`` for every block."""
    from dqcontrol.controllers.core.task_kernels import gram, task_matrices

    rng = np.random.default_rng(11)
    g = rng.standard_normal((9, 5))
    h = gram(g)
    np.testing.assert_allclose(h, g.T @ g, rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(h, h.T)
    p, n, gain = 4, 6, 7.5
    xs, xd, dxd = (rng.standard_normal((p, 8)) for _ in range(3))
    jacs = rng.standard_normal((p, 8, n))
    got = task_matrices(xs, jacs, xd, dxd, gain)
    want = np.concatenate((jacs, (gain * (xs - xd) - dxd)[:, :, None]), axis=2)
    np.testing.assert_array_equal(got, want)


def test_scatter_blocks_is_a_block_diagonal():
    import scipy.linalg

    from dqcontrol.controllers.core.task_kernels import scatter_blocks

    rng = np.random.default_rng(12)
    blocks = rng.standard_normal((3, 4, 4))
    h = np.full((12, 12), 5.0)  # entries off the blocks are left alone
    scatter_blocks(h, blocks)
    want = scipy.linalg.block_diag(*blocks)
    on = want != 0.0
    np.testing.assert_array_equal(h[on], want[on])
    np.testing.assert_array_equal(h[scipy.linalg.block_diag(*np.ones((3, 4, 4))) == 0.0], 5.0)


@pytest.mark.parametrize("flip", [False, True])
def test_measured_state_aligns_and_packs_one_block(flip):
    """``out = [x, jac (row-major), x_d, dx_d/dσ, q, σ]`` with ``x`` and ``jac`` negated
    where ``x · x_d < 0``, in place and in ``out``."""
    from dqcontrol.controllers.core.task_kernels import measured_state

    rng = np.random.default_rng(13 + flip)
    n = 7
    pair = rng.standard_normal((2, 8))
    x = rng.standard_normal(8)
    x *= np.sign(x @ pair[0]) * (-1.0 if flip else 1.0)  # the sign asked for
    jac, q, sigma = rng.standard_normal((8, n)), rng.standard_normal(n), 0.37
    sign = -1.0 if flip else 1.0
    want = np.concatenate((sign * x, sign * jac.ravel(), pair[0], pair[1], q, [sigma]))
    x_in, jac_in = x.copy(), jac.copy()
    out = np.empty(8 + 8 * n + 16 + n + 1)
    measured_state(x_in, jac_in, pair, q, sigma, out)
    np.testing.assert_array_equal(out, want)
    np.testing.assert_array_equal(x_in, sign * x)
    np.testing.assert_array_equal(jac_in, sign * jac)
