"""The first level's objective in one compiled call (:mod:`dqcontrol.controllers.core.objective`)
against :func:`~dqcontrol.controllers.core.problem.objective` on seeded random draws
(docs/theory.md §7.4): changing dense rows, and rows given through the predicted states
they read (``StateRows``) for the consistent prediction's weights (with and without a servo
lag) and for any weights."""

import numpy as np
import pytest

from dqcontrol.controllers.core.objective import level_objective
from dqcontrol.controllers.core.problem import DecisionLayout, Residual, StateRows, objective
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.prediction.consistent import (
    ConsistentPrediction,
    interval_breakpoints,
)


def _layout(joints, blocks):
    return DecisionLayout(joints, np.arange(blocks) * 0.1, np.full(blocks, 0.1))


def _draw(rng, layout, weighted, frozen_blocks):
    p, m, nv = layout.num_blocks, layout.block_size, layout.num_vars
    rows = rng.normal(size=(5, nv))
    rows[rng.random(size=rows.shape) < 0.4] = 0.0
    damping = np.tile(np.eye(m), (p, 1, 1))
    if frozen_blocks:
        frozen(damping)
    return (
        Residual(
            "path", 3.0, rng.normal(size=5), A=rows, row_weights=rng.random(5) if weighted else None
        ),  # fmt: skip
        Residual("damping", 1e-3, rng.normal(size=p * m), blocks=damping, held=False),
        Residual("off", 0.0, rng.normal(size=p), blocks=rng.normal(size=(p, 1, m)), held=False),
        Residual("blocks", 0.5, rng.normal(size=2 * p), blocks=rng.normal(size=(p, 2, m))),
    )


@pytest.mark.parametrize("weighted", [False, True])
@pytest.mark.parametrize("frozen_blocks", [False, True])
@pytest.mark.parametrize("seed", range(4))
def test_the_level_objective_is_objectives(seed, weighted, frozen_blocks):
    rng = np.random.default_rng(seed)
    layout = _layout(int(rng.integers(1, 4)), int(rng.integers(1, 4)))
    residuals = _draw(rng, layout, weighted, frozen_blocks)
    p_mat, c = level_objective(layout, residuals)
    p_ref, c_ref = objective(layout, residuals)
    assert p_mat.shape == p_ref.shape and c.shape == c_ref.shape
    assert np.allclose(p_mat, p_ref, rtol=1e-14, atol=1e-14)
    assert np.allclose(c, c_ref, rtol=1e-14, atol=1e-14)


def test_read_only_or_other_rows_are_left_to_objective():
    rng = np.random.default_rng(5)
    layout = _layout(2, 3)
    residuals = _draw(rng, layout, True, True)
    path = residuals[0]
    path = path._replace(A=frozen(path.A.copy()), row_weights=frozen(path.row_weights.copy()))
    kept = (path, residuals[1])
    p_mat, _ = level_objective(layout, kept)
    assert not p_mat.flags.writeable  # objective's kept product of read-only rows
    assert np.array_equal(p_mat, objective(layout, kept)[0])


def _dense(states: StateRows) -> np.ndarray:
    """``A`` ``(p r, p m)`` from the rows of each state, block by block."""
    p, r, m = states.rows.shape
    a = np.zeros((p * r, p * m))
    for i in range(p):
        for j in range(p):
            block = states.rows[i].copy()
            block[:, : m - 1] *= states.weights[i, j]
            block[:, m - 1] *= states.phase_weights[i, j]
            a[i * r : (i + 1) * r, j * m : (j + 1) * m] = block
    return a


def _weights(kind: str, model: ConsistentPrediction, rng: np.random.Generator) -> np.ndarray:
    p = model.layout.num_blocks
    if kind == "any":  # no structure: every block in every state
        return rng.normal(size=(p, p))
    return model.weights


@pytest.mark.parametrize(
    ("kind", "lag_s", "seed"),
    [("prediction", 0.0, 0), ("prediction", 0.004, 1), ("any", 0.0, 2), ("prediction", 0.0, 3)],
)
def test_objective_from_state_rows_equals_the_dense_one(kind, lag_s, seed):
    rng = np.random.default_rng(seed)
    n, period = 7, 1e-3
    model = ConsistentPrediction(interval_breakpoints(10, 1.0, period), n, period, 1.0, lag_s)
    layout = model.layout
    p = layout.num_blocks
    states = StateRows(
        rng.normal(size=(p, 6, n + 1)), _weights(kind, model, rng), model.sigma_weights
    )
    b, row_weights = rng.normal(size=6 * p), rng.uniform(0.1, 1.0, size=6 * p)
    a = _dense(states)
    eye = np.tile(np.eye(n + 1), (p, 1, 1))
    damping = Residual("damping", 1e-6, np.zeros(p * (n + 1)), blocks=eye)
    with_states = Residual("path", 1e4, b, A=a, row_weights=row_weights, states=states)
    dense = with_states._replace(states=None)
    p_ref, c_ref = objective(layout, (dense, damping))
    p_mat, c = level_objective(layout, (with_states, damping))
    assert np.abs(p_mat - p_ref).max() <= 1e-13 * np.abs(p_ref).max()
    assert np.abs(c - c_ref).max() <= 1e-13 * np.abs(c_ref).max()
    assert np.abs(p_mat - p_mat.T).max() <= 1e-15 * np.abs(p_ref).max()
    # the dense rows alone through the same function: the same objective as objective()
    p_dense, c_dense = level_objective(layout, (dense, damping))
    assert np.abs(p_dense - p_ref).max() <= 1e-13 * np.abs(p_ref).max()
    assert np.abs(c_dense - c_ref).max() <= 1e-13 * np.abs(c_ref).max()


def test_a_wrong_structure_would_be_seen():
    """The check can fail: state rows that do not match the dense rows give another
    objective."""
    rng = np.random.default_rng(7)
    n, period = 7, 1e-3
    model = ConsistentPrediction(interval_breakpoints(4, 0.2, period), n, period)
    p = model.layout.num_blocks
    states = StateRows(rng.normal(size=(p, 6, n + 1)), model.weights, model.sigma_weights)
    b = rng.normal(size=6 * p)
    wrong = states._replace(weights=model.weights * 1.001)
    res = Residual("path", 1.0, b, A=_dense(states), states=wrong)
    p_ref, _ = objective(model.layout, (res._replace(states=None),))
    p_mat, _ = level_objective(model.layout, (res,))
    assert np.abs(p_mat - p_ref).max() > 1e-6 * np.abs(p_ref).max()


@pytest.mark.parametrize("with_dense", [False, True])
def test_weighted_block_rows_count_their_row_weights(with_dense):
    """Rows given as blocks with row weights: ``P = 2 w Aᵀ diag(ρ) A`` and
    ``c = -2 w Aᵀ diag(ρ) b`` with ``A`` the block diagonal formed here, in both objectives
    and in the block assembly."""
    from scipy.linalg import block_diag

    from dqcontrol.controllers.core.block_assembly import add_residual

    rng = np.random.default_rng(2)
    layout = _layout(3, 3)
    blocks, rho, b = rng.normal(size=(3, 5, 4)), rng.uniform(0.5, 2.0, 15), rng.normal(size=15)
    res = Residual("r", 0.8, b, blocks=blocks, row_weights=rho)
    a = block_diag(*blocks)
    p_ref, c_ref = 2 * 0.8 * (a * rho[:, None]).T @ a, -2 * 0.8 * (a * rho[:, None]).T @ b
    residuals = (res,)
    if with_dense:  # a changing dense residual takes level_objective's compiled path
        rows = rng.normal(size=(4, layout.num_vars))
        residuals = (res, Residual("d", 0.5, rng.normal(size=4), A=rows))
        p_ref = p_ref + 2 * 0.5 * rows.T @ rows
        c_ref = c_ref - 2 * 0.5 * rows.T @ residuals[1].b
    for p_mat, c in (objective(layout, residuals), level_objective(layout, residuals)):
        np.testing.assert_allclose(p_mat, p_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(c, c_ref, rtol=1e-12, atol=1e-12)
    hessian, lin = np.zeros((3, 4, 4)), np.zeros(12)
    add_residual(hessian, lin, res)
    np.testing.assert_allclose(block_diag(*hessian), 2 * 0.8 * (a * rho[:, None]).T @ a, atol=1e-12)
