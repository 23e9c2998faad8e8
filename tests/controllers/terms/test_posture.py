"""The posture term (dqcontrol/controllers/terms/posture.py) and its compiled pull rows
against numpy: ``b = K_p s (q_ref - q̄_i)`` at the predicted states (docs/theory.md §8.3)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from controllers.terms.step_contexts import consistent_prediction

from dqcontrol.controllers.terms.posture import PostureTerm, pull_into
from dqcontrol.errors import ParameterError


def test_posture_rows_pull_towards_the_reference():
    model, pred, rng = consistent_prediction(8)
    term = PostureTerm(model.layout, 2.5)
    term.reference = rng.normal(size=pred.q_lin.shape[1])
    for scale in (1.0, 0.0):
        ctx = type("C", (), {"posture_scale": scale, "prediction": pred})()
        res = term.residual(ctx)
        expected = (2.5 * scale) * (term.reference - pred.q_lin)
        assert np.array_equal(res.b, expected.ravel())


def test_without_a_reference_it_pulls_towards_the_measured_configuration():
    model, pred, rng = consistent_prediction(9)
    term = PostureTerm(model.layout, 1.5, weight=0.2)
    q = rng.normal(size=pred.q_lin.shape[1])
    res = term.residual(SimpleNamespace(q=q, posture_scale=1.0, prediction=pred))
    np.testing.assert_allclose(res.b, (1.5 * (q - pred.q_lin)).ravel(), rtol=1e-15, atol=1e-15)
    assert res.weight == 0.2
    z = rng.normal(size=model.layout.num_vars)  # the rows are the joint velocities
    qd = z.reshape(model.layout.num_blocks, -1)[:, : pred.q_lin.shape[1]]
    np.testing.assert_allclose(res.value(model.layout, z), qd.ravel() - res.b, atol=1e-12)


@pytest.mark.parametrize(("p", "n"), [(1, 7), (6, 3)])
def test_pull_into_is_numpys_formula(p, n):
    rng = np.random.default_rng(p * 10 + n)
    reference, states = rng.normal(size=n), rng.normal(size=(p, n))
    out = np.full(p * n, np.nan)
    pull_into(reference, states, 0.7, out)
    np.testing.assert_array_equal(out, (0.7 * (reference - states)).ravel())


@pytest.mark.parametrize("gain", [0.0, -1.0, np.inf])
def test_a_gain_that_is_not_positive_is_refused(gain):
    model, _, _ = consistent_prediction(1)
    with pytest.raises(ParameterError, match="posture gain_per_s"):
        PostureTerm(model.layout, gain)
