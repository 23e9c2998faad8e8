"""Dense rows given through the predicted states they read (``StateRows``): the first
level's objective summed from each state's Gram matrix against the one of the dense rows,
for the weights of the consistent prediction with and without a servo lag, and for any
weights."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.objective import level_objective
from dqcontrol.controllers.core.problem import Residual, StateRows, objective
from dqcontrol.controllers.prediction.consistent import (
    ConsistentPrediction,
    interval_breakpoints,
)


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
