"""The thesis's prediction (dqcontrol/controllers/prediction/thesis.py) against its
definition: ``q + W qd_prev`` and the phase of each mode with ``W`` from the integration
matrix, the warm start from ``np.interp`` of the shifted plan, the one-block case."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.prediction import (
    ThesisPrediction,
    integration_matrix,
    prediction_instants,
)

T = 0.05


def _layout(p: int, n: int = 3) -> DecisionLayout:
    tau = prediction_instants(p, 1.0) if p > 1 else np.zeros(1)
    durations = np.append(np.diff(tau), np.diff(tau)[-1:]) if p > 1 else np.array([T])
    return DecisionLayout(n, tau, durations)


@pytest.mark.parametrize("phase", ["previous", "nominal"])
def test_the_states_are_the_integrated_previous_plan(phase):
    layout = _layout(6)
    model = ThesisPrediction(layout, T, phase)
    rng = np.random.default_rng(5)
    plan_qd, plan_s = rng.normal(size=(6, 3)), rng.uniform(0.0, 1.0, 6)
    model.commit(plan_qd, plan_s)
    q, sigma = rng.normal(size=3), 0.4
    pred = model.predict(q, sigma)
    w = integration_matrix(layout.instants_s, T)
    np.testing.assert_allclose(pred.q_lin, q + w @ plan_qd, rtol=0, atol=1e-15)
    expected_sigma = sigma + (w @ plan_s if phase == "previous" else layout.instants_s)
    np.testing.assert_allclose(pred.sigma_lin, expected_sigma, rtol=0, atol=1e-15)
    # data, not decision: the base is the state itself and the weights vanish
    assert pred.q_base is pred.q_lin and pred.sigma_base is pred.sigma_lin
    np.testing.assert_array_equal(pred.weights, np.zeros((6, 6)))
    assert pred.phase_weights is pred.weights  # no separate phase weights


def test_the_warm_start_is_the_plan_shifted_by_one_period():
    layout = _layout(5)
    tau = layout.instants_s
    rng = np.random.default_rng(6)
    plan_qd, plan_s = rng.normal(size=(5, 3)), rng.uniform(0.0, 1.0, 5)
    warm = ThesisPrediction(layout, T)
    warm.commit(plan_qd, plan_s)
    pred = warm.predict(np.zeros(3), 0.0)
    for k in range(3):
        np.testing.assert_allclose(pred.warm_qd[:, k], np.interp(tau + T, tau, plan_qd[:, k]))
    np.testing.assert_allclose(pred.warm_s, np.interp(tau + T, tau, plan_s))
    cold = ThesisPrediction(layout, T, warm=False)
    cold.commit(plan_qd, plan_s)
    pred = cold.predict(np.zeros(3), 0.0)
    assert pred.warm_qd is None and pred.warm_s is None


def test_reset_holds_the_start_velocity_at_full_scaling():
    layout = _layout(4)
    model = ThesisPrediction(layout, T)
    model.reset(np.zeros(3), np.array([0.1, 0.2, 0.3]))
    np.testing.assert_array_equal(model.horizon_qd, [[0.1, 0.2, 0.3]] * 4)
    np.testing.assert_array_equal(model.horizon_s, np.ones(4))
    plan = np.ones((4, 3))
    model.commit(plan, np.ones(4))
    plan[1, 1] = 5.0  # the model keeps its own copy
    assert model.horizon_qd[1, 1] == 1.0


def test_one_block_predicts_the_measured_state_in_one_reused_object():
    model = ThesisPrediction(_layout(1), T)
    first = model.predict(np.array([1.0, 2.0, 3.0]), 0.25)
    np.testing.assert_array_equal(first.q_lin, [[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(first.sigma_lin, [0.25])
    second = model.predict(np.array([4.0, 5.0, 6.0]), 0.5)
    assert second is first
    np.testing.assert_array_equal(first.q_base, [[4.0, 5.0, 6.0]])
    np.testing.assert_array_equal(first.sigma_base, [0.5])
    assert first.warm_qd is None and first.warm_s is None
