"""The trust region (dqcontrol/controllers/limits/trust_region.py): its bands around the
prediction's linearisation against numpy (docs/theory.md §8.5), and its compiled band
kernels entry by entry."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.step_contexts import PredictionContext, consistent_prediction

from dqcontrol.controllers.limits.trust_region import TrustRegionLimit, band_into, bands_into


@pytest.mark.parametrize(("radius", "phase"), [(0.1, 0.05), (0.1, np.inf), (np.inf, 0.05)])
def test_trust_region_bands(radius, phase):
    model, pred, _ = consistent_prediction(7)
    limit = TrustRegionLimit(model.layout, radius, phase, 0.2)
    got = {g.name: g for g in limit.rows(PredictionContext(pred, None))}
    ends = model.layout.instants_s + model.layout.durations_s
    grow = 1.0 + ends / 0.2
    n = pred.q_lin.shape[1]
    centre_q = (pred.q_lin - pred.q_base).ravel()
    centre_s = pred.sigma_lin - pred.sigma_base
    expected = {}
    if np.isfinite(radius):
        r = np.repeat(radius * grow, n)
        expected["trust_region_q"] = (centre_q - r, centre_q + r)
    if np.isfinite(phase):
        expected["trust_region_phase"] = (centre_s - phase * grow, centre_s + phase * grow)
    assert set(got) == set(expected)
    for name, (lo, up) in expected.items():
        assert np.array_equal(got[name].lower, lo) and np.array_equal(got[name].upper, up)


def test_band_kernels_are_numpys_centre_and_radius():
    rng = np.random.default_rng(12)
    p, n = 4, 3
    q, q_base, q_r = rng.normal(size=(p, n)), rng.normal(size=(p, n)), rng.uniform(0, 1, p * n)
    s, s_base, s_r = rng.normal(size=p), rng.normal(size=p), rng.uniform(0, 1, p)
    lower, upper = np.full(p * n + p, np.nan), np.full(p * n + p, np.nan)
    bands_into(q, q_base, q_r, s, s_base, s_r, lower, upper)
    centre = np.r_[(q - q_base).ravel(), s - s_base]
    radius = np.r_[q_r, s_r]
    assert np.array_equal(lower, centre - radius) and np.array_equal(upper, centre + radius)
    one_lo, one_up = np.empty(p), np.empty(p)
    band_into(s, s_base, s_r, one_lo, one_up)
    assert np.array_equal(one_lo, lower[p * n :]) and np.array_equal(one_up, upper[p * n :])
