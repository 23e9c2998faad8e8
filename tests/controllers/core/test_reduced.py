"""A level's objective and rows in a null-space basis (docs/theory.md §7.4), against the
dense formation ``Zᵀ P Z``, ``Zᵀ (P z₀ + c)``, ``[I; A Z]`` on seeded random draws."""

import numpy as np
import pytest
from controllers.core.test_levels import _problem

from dqcontrol.controllers.core.levels import level_in_basis
from dqcontrol.controllers.core.problem import DecisionLayout, Residual, objective
from dqcontrol.controllers.core.reduced import (
    level_rows,
    nonzero_entries,
    objective_in_basis,
    reduced_objective,
    rows_in_basis,
    sparse_product,
)
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.linalg.null_space import null_space


def _sparse(rng, rows, cols, share):
    a = rng.normal(size=(rows, cols))
    a[rng.random(size=a.shape) > share] = 0.0
    return a


def _layout(joints, blocks):
    return DecisionLayout(joints, np.arange(blocks) * 0.1, np.full(blocks, 0.1))


def _residuals(rng, layout, read_only):
    """One of each form: blocks, dense, row weights, not held, zero weight."""
    p, m, nv = layout.num_blocks, layout.block_size, layout.num_vars
    keep = frozen if read_only else (lambda a: a)
    out = [
        Residual(
            "blocks",
            0.7,
            rng.normal(size=2 * p),
            blocks=keep(_sparse(rng, p, 2, 0.5).reshape(p, 2, 1) * rng.normal(size=(p, 2, m))),
        ),  # fmt: skip
        Residual("dense", 2.0, rng.normal(size=3), A=keep(_sparse(rng, 3, nv, 0.3))),
        Residual(
            "weighted",
            1.5,
            rng.normal(size=4),
            A=keep(_sparse(rng, 4, nv, 0.6)),
            row_weights=rng.random(4),
        ),  # fmt: skip
        Residual(
            "free", 0.3, rng.normal(size=p), blocks=keep(rng.normal(size=(p, 1, m))), held=False
        ),  # fmt: skip
        Residual("zero", 0.0, rng.normal(size=2), A=keep(rng.normal(size=(2, nv))), held=False),
        Residual(
            "damping", 1e-3, np.zeros(nv), blocks=keep(np.tile(np.eye(m), (p, 1, 1))), held=False
        ),  # fmt: skip
    ]
    return tuple(out)


@pytest.mark.parametrize("read_only", [False, True])
@pytest.mark.parametrize("seed", range(4))
def test_sparse_product_is_the_dense_one(seed, read_only):
    rng = np.random.default_rng(seed)
    a = _sparse(rng, 13, 9, 0.3)
    if read_only:
        frozen(a)
    right = rng.normal(size=(9, 4))
    assert np.allclose(sparse_product(a, right), a @ right, rtol=1e-13, atol=1e-13)
    entries = nonzero_entries(a)
    assert entries.shape == (np.count_nonzero(a), 3)
    assert np.array_equal(a[entries[:, 0].astype(int), entries[:, 1].astype(int)], entries[:, 2])


@pytest.mark.parametrize("read_only", [False, True])
@pytest.mark.parametrize("seed", range(6))
def test_the_reduced_objective_is_the_dense_one_in_the_basis(seed, read_only):
    rng = np.random.default_rng(seed)
    layout = _layout(int(rng.integers(1, 4)), int(rng.integers(2, 5)))
    nv = layout.num_vars
    residuals = _residuals(rng, layout, read_only)
    basis = null_space(rng.normal(size=(int(rng.integers(1, nv)), nv)))
    point = rng.normal(size=nv)
    reduced = reduced_objective(residuals, point, basis)
    p_mat, c = objective(layout, residuals)
    scale = max(1.0, np.abs(p_mat).max())
    assert np.array_equal(reduced.hessian, reduced.hessian.T)
    assert np.allclose(reduced.hessian, basis.T @ p_mat @ basis, rtol=0, atol=1e-12 * scale)
    expected = basis.T @ (p_mat @ point + c)
    assert np.allclose(reduced.gradient, expected, rtol=0, atol=1e-12 * scale)
    held = np.vstack([r.dense(layout) for r in residuals if r.held])
    assert np.allclose(reduced.held, held @ basis, rtol=0, atol=1e-12)


@pytest.mark.parametrize("read_only", [False, True])
@pytest.mark.parametrize("seed", range(4))
def test_the_rows_in_the_basis_are_those_of_i_and_c(seed, read_only):
    rng = np.random.default_rng(seed)
    nv, dim, general = 9, 4, 7
    c = _sparse(rng, general, nv, 0.3)
    if read_only:
        frozen(c)
    basis, _ = np.linalg.qr(rng.normal(size=(nv, dim)))
    point = rng.normal(size=nv)
    lower = -rng.random(nv + general)
    upper = rng.random(nv + general)
    rows, lo, up = rows_in_basis(c, basis, point, lower, upper)
    full = np.vstack([np.eye(nv), c])
    assert np.array_equal(rows[:dim], np.eye(dim))
    assert np.allclose(rows[dim:], full @ basis, rtol=0, atol=1e-13)
    assert np.all(np.isneginf(lo[:dim])) and np.all(np.isposinf(up[:dim]))
    assert np.allclose(lo[dim:], lower - full @ point, rtol=0, atol=1e-13)
    assert np.allclose(up[dim:], upper - full @ point, rtol=0, atol=1e-13)


@pytest.mark.parametrize("seed", range(5))
def test_the_reduced_qp_is_the_level_in_the_basis(seed):
    problem = _problem(seed, 3, 3, (4, 2), tight=False)
    rng = np.random.default_rng(seed)
    nv = problem.layout.num_vars
    held = np.vstack([r.dense(problem.layout) for r in problem.levels[0].residuals if r.held])
    basis = null_space(held)
    point = rng.normal(size=nv)
    reduced = level_in_basis(problem, 1, point, basis)
    qp = reduced.dense(reduced.objective())
    p_mat, c = objective(problem.layout, problem.levels[1].residuals)
    dim = basis.shape[1]
    scale = max(1.0, np.abs(p_mat).max())
    assert np.allclose(qp.P, basis.T @ p_mat @ basis, rtol=0, atol=1e-12 * scale)
    assert np.allclose(qp.c, basis.T @ (p_mat @ point + c), rtol=0, atol=1e-12 * scale)
    assert np.allclose(qp.A, np.vstack([np.eye(dim), problem.A @ basis]), rtol=0, atol=1e-13)
    shift = problem.A @ point
    assert np.allclose(qp.lower[dim:], problem.lower - shift, rtol=0, atol=1e-13)
    assert np.allclose(qp.upper[dim:], problem.upper - shift, rtol=0, atol=1e-13)


def test_level_rows_follow_changed_weights_and_writable_rows():
    rng = np.random.default_rng(3)
    point, basis = rng.normal(size=6), np.linalg.qr(rng.normal(size=(6, 4)))[0]
    rows = frozen(rng.normal(size=(3, 6)))
    first = (Residual("a", 1.0, rng.normal(size=3), A=rows),)
    again = (Residual("a", 2.0, first[0].b, A=rows),)  # the same rows, another weight
    for residuals in (first, again, first):
        got = objective_in_basis(level_rows(residuals), point, basis)
        dense = 2.0 * residuals[0].weight * (rows @ basis).T @ (rows @ basis)
        np.testing.assert_allclose(got.hessian, dense, rtol=1e-12)
    writable = rng.normal(size=(3, 6))
    live = (Residual("b", 1.0, rng.normal(size=3), A=writable),)
    before = reduced_objective(live, point, basis).hessian
    writable *= 2.0  # rows that may change are read again at every call
    np.testing.assert_allclose(reduced_objective(live, point, basis).hessian, 4.0 * before)


def test_level_rows_of_strided_blocks_are_their_dense_rows():
    # a term may give a view of wider blocks (the tracking term's rows without the s column)
    rng = np.random.default_rng(5)
    wide = rng.normal(size=(3, 4, 6))
    wide[np.abs(wide) < 0.5] = 0.0
    blocks = wide[:, :, :5]
    residual = Residual("view", 0.5, rng.normal(size=12), blocks=blocks)
    dense = np.zeros((12, 15))
    for i in range(3):
        dense[4 * i : 4 * i + 4, 5 * i : 5 * i + 5] = blocks[i]
    point, basis = rng.normal(size=15), np.linalg.qr(rng.normal(size=(15, 6)))[0]
    got = reduced_objective((residual,), point, basis)
    rows = dense @ basis
    np.testing.assert_allclose(got.hessian, 2.0 * 0.5 * rows.T @ rows, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(
        got.gradient, 2.0 * 0.5 * rows.T @ (dense @ point - residual.b), rtol=1e-12, atol=1e-14
    )
