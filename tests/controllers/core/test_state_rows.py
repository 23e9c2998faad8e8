"""The compiled kernel of :mod:`dqcontrol.controllers.core.state_rows` (dense rows from the
rows of each predicted state) against numpy, also as read by ``Residual.dense``."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.problem import DecisionLayout, Residual, StateRows
from dqcontrol.controllers.core.state_rows import state_rows_into


def _numpy_rows(rows, weights, phase_weights) -> np.ndarray:
    """``(p, r, q, n + 1)``: block ``(i, j)`` is ``rows[i]`` with its first ``n`` columns
    times ``weights[i, j]`` and its last times ``phase_weights[i, j]``."""
    scale = np.concatenate(
        (np.repeat(weights[:, :, None], rows.shape[2] - 1, axis=2), phase_weights[:, :, None]),
        axis=2,
    )  # (p, q, n + 1)
    return rows[:, :, None, :] * scale[:, None, :, :]


@pytest.mark.parametrize(("p", "q", "r", "n"), [(1, 1, 6, 7), (4, 4, 3, 7), (3, 5, 2, 2)])
def test_state_rows_into_is_the_weighted_rows(p, q, r, n):
    rng = np.random.default_rng(p * 100 + q * 10 + n)
    rows = rng.normal(size=(p, r, n + 1))
    weights, phase_weights = rng.normal(size=(p, q)), rng.normal(size=(p, q))
    out = np.full((p, r, q, n + 1), np.nan)
    state_rows_into(rows, weights, phase_weights, out)
    np.testing.assert_array_equal(out, _numpy_rows(rows, weights, phase_weights))


def test_a_residual_given_by_states_is_dense_block_by_block():
    rng = np.random.default_rng(3)
    p, r, n = 3, 4, 5
    layout = DecisionLayout(n, np.arange(p) * 0.1, np.full(p, 0.1))
    states = StateRows(rng.normal(size=(p, r, n + 1)), rng.normal(size=(p, p)),
                       rng.normal(size=(p, p)))  # fmt: skip
    a = Residual("path", 1.0, np.zeros(p * r), states=states).dense(layout)
    assert a.shape == (p * r, layout.num_vars)
    m = n + 1
    for i in range(p):
        for j in range(p):
            block = a[i * r : (i + 1) * r, j * m : (j + 1) * m]
            np.testing.assert_array_equal(
                block[:, :n], states.weights[i, j] * states.rows[i][:, :n]
            )
            np.testing.assert_array_equal(
                block[:, n], states.phase_weights[i, j] * states.rows[i][:, n]
            )
