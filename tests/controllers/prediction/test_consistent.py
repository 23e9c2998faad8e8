"""The consistent prediction (dqcontrol/controllers/prediction/consistent.py): its
breakpoints against their formula, the shift matrix against sampled averages, the predicted
states against the integrated plan and, behind a velocity lag, a fine simulation of it
(seeded random draws)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from dqcontrol.controllers.prediction.consistent import (
    ConsistentPrediction,
    interval_breakpoints,
    shift_matrix,
)
from dqcontrol.errors import ParameterError


def test_breakpoints_first_interval_is_the_period_and_grow():
    b = interval_breakpoints(10, 1.0, 0.05)
    assert b[0] == 0.0 and b[1] == pytest.approx(0.05) and b[-1] == pytest.approx(1.0)
    assert np.all(np.diff(np.diff(b[1:])) > 0.0)


def test_breakpoints_grow_as_the_given_power():
    k = np.arange(1, 11, dtype=float)
    for growth in (2.0, 3.0, 1.0):
        b = interval_breakpoints(10, 1.0, 0.001, growth)
        expected = 0.001 + 0.999 * ((k - 1.0) / 9.0) ** growth  # b_1 … b_10
        np.testing.assert_allclose(b[1:], expected, rtol=1e-15)
    default = interval_breakpoints(10, 1.0, 0.001)
    np.testing.assert_array_equal(default, interval_breakpoints(10, 1.0, 0.001, 2.0))
    with pytest.raises(ParameterError, match="growth"):
        interval_breakpoints(10, 1.0, 0.001, 0.5)


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        ((1, 1.0, 0.01), "num_intervals"),
        ((True, 1.0, 0.01), "num_intervals"),
        ((2.5, 1.0, 0.01), "num_intervals"),
        ((5, 0.0, 0.01), "horizon_s"),
        ((5, np.inf, 0.01), "horizon_s"),
        ((5, 0.01, 0.01), "longer than the control period"),
    ],
)
def test_bad_breakpoints_are_named(args, fragment):
    with pytest.raises(ParameterError, match=fragment):
        interval_breakpoints(*args)


def test_shift_matrix_rows_are_averages():
    b = interval_breakpoints(6, 1.0, 0.05)
    s = shift_matrix(b, 0.05)
    np.testing.assert_allclose(s.sum(axis=1), 1.0)
    v = np.arange(6.0)
    # the mean of the shifted piecewise-constant profile, computed by fine sampling
    fine = np.linspace(0.0, 2.0, 400001)
    idx = np.minimum(np.searchsorted(b, fine, side="right") - 1, 5)
    for i in range(6):
        mask = (fine >= b[i] + 0.05) & (fine < b[i + 1] + 0.05)
        assert (s @ v)[i] == pytest.approx(v[idx[mask]].mean(), abs=1e-3)


@pytest.mark.parametrize("lag_s", [0.0, 0.004])
def test_the_prediction_is_the_integrated_plan(lag_s):
    breaks = interval_breakpoints(5, 0.5, 0.01)
    model = ConsistentPrediction(breaks, 3, 0.01, 1.0, lag_s)
    rng = np.random.default_rng(2)
    model.commit(rng.normal(size=(5, 3)), rng.uniform(-0.5, 1.5, 5))
    model.qd_measured = rng.normal(size=3)
    q = rng.normal(size=3)
    pred = model.predict(q, 0.3)
    shift = model._shift
    qd_lin = shift @ model.plan_qd
    s_lin = np.clip(shift @ model.plan_s, 0.0, 1.0)
    base = q + model._v0_weights[:, None] * model.qd_measured if lag_s else np.tile(q, (5, 1))
    np.testing.assert_array_equal(pred.warm_s, s_lin)
    np.testing.assert_array_equal(pred.q_lin, base + model.weights @ qd_lin)
    np.testing.assert_array_equal(pred.sigma_lin, 0.3 + model.sigma_weights @ s_lin)
    np.testing.assert_array_equal(pred.q_base, base)
    np.testing.assert_array_equal(pred.sigma_base, np.full(5, 0.3))


def test_behind_a_velocity_lag_the_states_are_the_simulated_joints():
    """The states at the breakpoints behind a first-order velocity lag against the exact
    solution of ``dq/dt = v``, ``dv/dt = (qd_j - v)/τ_v`` over each interval (the matrix
    exponential of the augmented linear system), from the measured velocity."""
    period, lag = 0.01, 0.004
    breaks = interval_breakpoints(4, 0.2, period)
    model = ConsistentPrediction(breaks, 2, period, 1.0, lag)
    rng = np.random.default_rng(4)
    qd, v0, q = rng.normal(size=(4, 2)), rng.normal(size=2), rng.normal(size=2)
    model.qd_measured = v0
    pred = model.at(q, 0.0, qd, np.zeros(4))
    # state (q, v, 1): the constant command enters through the last column
    states = []
    for k in range(2):
        x = np.array([q[k], v0[k], 1.0])
        for j, duration in enumerate(np.diff(breaks)):
            a = np.array([[0.0, 1.0, 0.0], [0.0, -1.0 / lag, qd[j, k] / lag], [0.0, 0.0, 0.0]])
            x = expm(a * duration) @ x
            states.append((j, k, x[0]))
    exact = np.empty((4, 2))
    for j, k, value in states:
        exact[j, k] = value
    np.testing.assert_allclose(pred.q_lin, exact, rtol=0, atol=1e-13)
    # the first state alone, as the linearisation check takes it
    np.testing.assert_allclose(model.state_after_first(q, qd[0]), pred.q_lin[0], atol=1e-15)


def test_reset_holds_the_start_velocity_and_no_progress():
    model = ConsistentPrediction(interval_breakpoints(3, 0.1, 0.01), 2, 0.01)
    model.reset(np.zeros(2), np.array([0.5, -1.0]))
    np.testing.assert_array_equal(model.plan_qd, [[0.5, -1.0]] * 3)
    np.testing.assert_array_equal(model.plan_s, np.zeros(3))
    plan = np.ones((3, 2))
    model.commit(plan, np.ones(3))
    plan[0, 0] = 7.0  # the model keeps its own copy
    assert model.plan_qd[0, 0] == 1.0
