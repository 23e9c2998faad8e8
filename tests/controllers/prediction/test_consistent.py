"""The compiled element-wise parts of the consistent prediction and of the context's sign
alignment against the numpy expressions they stand for (seeded random draws)."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.context import align_into
from dqcontrol.controllers.prediction.consistent import (
    ConsistentPrediction,
    interval_breakpoints,
)
from dqcontrol.controllers.prediction.consistent_kernels import clip_into, states_into


def test_clip_into_is_numpys_clip():
    values = np.random.default_rng(0).normal(size=50) * 2.0
    values[[3, 7]] = [np.nan, -0.0]
    expected = np.minimum(np.maximum(values, 0.0), 1.3)
    clip_into(values, 0.0, 1.3)
    np.testing.assert_array_equal(values, expected)


@pytest.mark.parametrize("lagging", [False, True])
def test_states_into_adds_the_zero_decisions_states(lagging):
    rng = np.random.default_rng(1)
    p, n = 6, 7
    q, v0, qd, sigma = rng.normal(size=n), rng.uniform(size=p), rng.normal(size=n), 0.7
    moved, advanced = rng.normal(size=(p, n)), rng.normal(size=p)
    base = q + v0[:, None] * qd if lagging else np.repeat(q[None, :], p, axis=0)
    expected = (base + moved, sigma + advanced)
    q_base, sigma_base = np.empty((p, n)), np.empty(p)
    states_into(q, v0, qd, lagging, sigma, moved, advanced, q_base, sigma_base)
    assert np.array_equal(q_base, base) and np.array_equal(sigma_base, np.full(p, sigma))
    assert np.array_equal(moved, expected[0]) and np.array_equal(advanced, expected[1])


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


def test_align_into_negates_the_poses_on_the_far_side():
    rng = np.random.default_rng(3)
    wide = rng.normal(size=(6, 8 + 8 * 7))  # poses beside their Jacobians, as a batch gives
    xs, jacs = wide[:, :8], wide[:, 8:].reshape(6, 8, 7)
    xd = xs + rng.normal(scale=0.1, size=(6, 8))
    xd[::2] *= -1.0
    flip = np.einsum("pk,pk->p", xs, xd) < 0.0
    assert flip.any() and not flip.all()
    expected = (np.where(flip[:, None], -xs, xs), np.where(flip[:, None, None], -jacs, jacs))
    align_into(xs, jacs, xd)
    assert np.array_equal(xs, expected[0]) and np.array_equal(jacs, expected[1])
