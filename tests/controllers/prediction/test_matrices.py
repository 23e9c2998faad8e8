"""Prediction instants and the integration and interpolation matrices
(dqcontrol/controllers/prediction/matrices.py) against eq. 3.15, fine numerical integration
and ``np.interp`` of the shifted profile."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers import integration_matrix, prediction_instants
from dqcontrol.controllers.prediction.matrices import interpolation_matrix
from dqcontrol.errors import ParameterError

T = 0.05


def test_prediction_instants_are_parabolic():
    tau = prediction_instants(10, 1.0)
    assert tau[0] == 0.0 and tau[-1] == pytest.approx(1.0)
    np.testing.assert_allclose(tau, (np.arange(10) / 9.0) ** 2)


@pytest.mark.parametrize(
    ("count", "horizon_s", "fragment"),
    [(1, 1.0, "p must be an integer ≥ 2"), (2.5, 1.0, "p must be"), (5, 0.0, "tau_p"),
     (5, np.nan, "tau_p")],
)  # fmt: skip
def test_bad_instants_are_named(count, horizon_s, fragment):
    with pytest.raises(ParameterError, match=fragment):
        prediction_instants(count, horizon_s)


def test_integration_matrix_integrates_the_shifted_profile():
    rng = np.random.default_rng(3)
    tau = prediction_instants(6, 1.0)
    v = rng.normal(size=6)
    w = integration_matrix(tau, T)

    def g(t):  # the previous profile, held past the horizon
        return np.interp(t, tau, v)

    for i, ti in enumerate(tau):
        grid = np.linspace(0.0, ti, 200001)
        exact = np.trapezoid(g(grid + T), grid)
        assert w[i] @ v == pytest.approx(exact, abs=1e-8)


@pytest.mark.parametrize(("p", "shift_s"), [(6, 0.05), (10, 0.001), (4, 2.0)])
def test_interpolation_matrix_evaluates_the_shifted_profile(p, shift_s):
    """``S v`` is the profile through ``(τ_j, v_j)`` at ``τ_i + shift``, held at its last
    value past the horizon (``np.interp`` holds its ends the same way)."""
    rng = np.random.default_rng(p)
    tau = prediction_instants(p, 1.0)
    s = interpolation_matrix(tau, shift_s)
    np.testing.assert_allclose(s.sum(axis=1), 1.0, rtol=1e-15)
    for _ in range(5):
        v = rng.normal(size=p)
        np.testing.assert_allclose(s @ v, np.interp(tau + shift_s, tau, v), rtol=0, atol=1e-14)


def test_without_a_shift_the_matrices_are_identity_and_plain_integration():
    tau = prediction_instants(5, 1.0)
    np.testing.assert_array_equal(interpolation_matrix(tau, 0.0), np.eye(5))
    # a constant profile integrates to its value times the instant
    np.testing.assert_allclose(integration_matrix(tau, 0.0) @ np.ones(5), tau, atol=1e-15)
