"""The compiled path-error kernels (dqcontrol/controllers/terms/path_error_kernels.py)
against a plain numpy formation of the same formula (docs/theory.md §8.2), on seeded random
states. (The summation order of ``lane_dot`` they sum with is tested in
tests/controllers/linalg/test_lanes.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.state_rows import state_rows_into
from dqcontrol.controllers.terms.path_error import PROJECTOR_BASIS
from dqcontrol.controllers.terms.path_error_kernels import path_states_into, projectors_into
from dqcontrol.dq.algebra import hamiplus8

PURE = [1, 2, 3, 5, 6, 7]


def path_rows_into(*args) -> None:
    """The state rows and ``b`` (:func:`path_states_into`), and the dense rows formed from
    them (:func:`state_rows_into`): ``args`` the states' inputs, the weights, the basis,
    then ``rows``, ``b``, ``states``."""
    *inputs, weights, phase_weights, basis, rows, b, states = args
    path_states_into(*inputs, basis, b, states)
    state_rows_into(states, weights, phase_weights, rows)


CONJ = np.array([1.0, -1.0, -1.0, -1.0, 1.0, -1.0, -1.0, -1.0])


def numpy_path_rows(x, xd, dxd, jac, q_base, q_lin, s_base, s_lin, w, w_s):
    """``A`` ``(6 p, p (n + 1))`` and ``b`` by matrix products: ``E_i = P H+8(x_i*)``."""
    p, n = q_lin.shape
    a = np.zeros((6 * p, p * (n + 1)))
    b = np.zeros(6 * p)
    for i in range(p):
        e = hamiplus8(CONJ * x[i])[PURE]
        ej, ed = e @ jac[i], e @ dxd[i]
        for j in range(p):
            a[6 * i : 6 * i + 6, j * (n + 1) : j * (n + 1) + n] = w[i, j] * ej
            a[6 * i : 6 * i + 6, j * (n + 1) + n] = -w_s[i, j] * ed
        gap = e @ (x[i] - xd[i]) + ej @ (q_base[i] - q_lin[i]) - ed * (s_base[i] - s_lin[i])
        b[6 * i : 6 * i + 6] = -gap
    return a, b


@pytest.mark.parametrize(("p", "n", "seed"), [(1, 7, 0), (4, 6, 1), (10, 7, 2), (5, 9, 3)])
def test_path_rows_equal_the_numpy_formation(p, n, seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(p, 8))
    x /= np.linalg.norm(x[:, :4], axis=1)[:, None]
    args = (
        x, x + rng.normal(scale=0.1, size=(p, 8)), rng.normal(size=(p, 8)),
        rng.normal(size=(p, 8, n)), rng.normal(size=(p, n)), rng.normal(size=(p, n)),
        rng.normal(size=p), rng.normal(size=p),
        np.tril(rng.uniform(size=(p, p))), np.tril(rng.uniform(size=(p, p))),
    )  # fmt: skip
    blocks, b = np.empty((p, 6, p, n + 1)), np.empty(6 * p)
    states = np.empty((p, 6, n + 1))
    path_rows_into(*args, PROJECTOR_BASIS, blocks, b, states)
    a_ref, b_ref = numpy_path_rows(*args)
    np.testing.assert_allclose(blocks.reshape(6 * p, -1), a_ref, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(b, b_ref, rtol=1e-13, atol=1e-14)
    # the rows of each state, through the weights, are the dense rows exactly
    w, w_s = args[8], args[9]
    for i in range(p):
        for j in range(p):
            assert np.array_equal(blocks[i, :, j, :n], w[i, j] * states[i, :, :n])
            assert np.array_equal(blocks[i, :, j, n], w_s[i, j] * states[i, :, n])


def test_path_rows_on_strided_poses_equal_contiguous_ones():
    rng = np.random.default_rng(5)
    p, n = 3, 7
    wide = rng.normal(size=(p, 8 + 8 * n))  # the poses as a view with the Jacobians beside
    x = wide[:, :8]
    jac = wide[:, 8:].reshape(p, 8, n)
    rest = (rng.normal(size=(p, 8)), rng.normal(size=(p, 8)))
    tail = (np.zeros((p, n)), rng.normal(size=(p, n)), np.zeros(p), np.ones(p))
    tail += (np.tril(np.ones((p, p))), np.tril(np.ones((p, p))), PROJECTOR_BASIS)
    out = [(np.empty((p, 6, p, n + 1)), np.empty(6 * p), np.empty((p, 6, n + 1))) for _ in range(2)]
    path_rows_into(x, *rest, jac, *tail, *out[0])
    path_rows_into(x.copy(), *rest, jac.copy(), *tail, *out[1])
    for strided, contiguous in zip(*out, strict=True):
        assert np.array_equal(strided, contiguous)


@pytest.mark.parametrize("p", [1, 4])
def test_projectors_are_the_pure_rows_of_the_conjugates_operator(p):
    poses = np.random.default_rng(20 + p).normal(size=(p, 8))
    out = np.full((p, 6, 8), np.nan)
    projectors_into(poses, PROJECTOR_BASIS, out)
    expected = np.array([hamiplus8(CONJ * x)[PURE] for x in poses])
    np.testing.assert_allclose(out, expected, rtol=1e-15, atol=1e-15)
