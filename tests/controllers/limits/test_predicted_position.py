"""The predicted position limit (dqcontrol/controllers/limits/predicted_position.py): the rows
it keeps are those a predicted state can reach, against a numpy selection of the full rows
(docs/theory.md §8.4), on seeded draws."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.step_contexts import PredictionContext, consistent_prediction

from dqcontrol.controllers.limits.predicted_position import PredictedPositionLimit


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("terminal", [True, False])
def test_predicted_position_rows_are_the_reachable_ones(seed, terminal):
    model, pred, rng = consistent_prediction(seed)
    p, n = pred.q_lin.shape
    q_min, q_max = -np.full(n, 1.0), np.full(n, 1.0)
    qd_max = rng.uniform(1.0, 2.0, n)
    reach = rng.uniform(0.0, 0.8, p)
    a_max = rng.uniform(2.0, 5.0, (p, n))
    limit = PredictedPositionLimit(
        model.layout, q_min, q_max, qd_max, terminal=terminal, reach_rad=reach
    )
    out = limit.rows(PredictionContext(pred, a_max)) or ()
    full = {g.name: g for g in PredictedPositionLimit(
        model.layout, q_min, q_max, qd_max, terminal=terminal
    ).rows(PredictionContext(pred, a_max))}  # fmt: skip
    near = (pred.q_lin + reach[:, None] >= q_max) | (pred.q_lin - reach[:, None] <= q_min)
    coeff = qd_max / (2.0 * a_max[-1])
    r_end = reach[-1] + coeff * qd_max
    near_end = (pred.q_lin[-1] + r_end >= q_max) | (pred.q_lin[-1] - r_end <= q_min)
    expected = {"predicted_position": near.ravel(), "terminal_braking": near_end}
    if not terminal:
        del expected["terminal_braking"]
    got = {g.name: g for g in out}
    assert set(got) == {k for k, mask in expected.items() if mask.any()}
    for name, g in got.items():
        mask = expected[name]
        assert np.array_equal(g.C, full[name].C[mask])
        assert np.array_equal(g.lower, full[name].lower[mask])
        assert np.array_equal(g.upper, full[name].upper[mask])


def test_set_bounds_moves_the_rows_bounds_and_nothing_else():
    model, pred, rng = consistent_prediction(3)
    p, n = pred.q_lin.shape
    q_min, q_max = -np.full(n, 1.0), np.full(n, 1.0)
    qd_max, a_max = np.full(n, 1.5), np.full((p, n), 3.0)
    limit = PredictedPositionLimit(model.layout, q_min, q_max, qd_max)
    ctx = PredictionContext(pred, a_max)
    before = {g.name: g for g in limit.rows(ctx)}
    shift = rng.uniform(0.0, 0.1, n)
    limit.set_bounds(q_min + shift, q_max - shift)
    assert np.array_equal(q_min, -np.ones(n)) and np.array_equal(q_max, np.ones(n))  # theirs
    moved = {g.name: g for g in limit.rows(ctx)}
    fresh = {g.name: g for g in PredictedPositionLimit(
        model.layout, q_min + shift, q_max - shift, qd_max
    ).rows(ctx)}  # fmt: skip
    for name, g in moved.items():
        assert g.C is before[name].C or np.array_equal(g.C, before[name].C)  # the rows stay
        assert np.array_equal(g.lower, fresh[name].lower)
        assert np.array_equal(g.upper, fresh[name].upper)
