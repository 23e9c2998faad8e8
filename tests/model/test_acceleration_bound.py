"""The dynamics-aware acceleration bound of a batch of configurations (docs/theory.md §5)
against the bound of each configuration, and against ``M(q)`` and ``g(q)`` directly."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0


@pytest.mark.parametrize(("fraction", "floor", "cap"), [(1.0, 0.5, 50.0), (0.6, 2.0, 8.0)])
def test_the_batch_is_each_configurations_bound(lbr4p, fraction, floor, cap):
    qs = LBR4P_Q0 + np.random.default_rng(3).uniform(-0.8, 0.8, (6, lbr4p.nq))
    batch = lbr4p.fast.acceleration_limits_batch(qs, fraction, floor, cap)
    rows = [lbr4p.fast.acceleration_limits(q, fraction, floor, cap) for q in qs]
    assert np.array_equal(batch, np.array(rows))
    for q, a in zip(qs, batch, strict=True):
        m, g = lbr4p.mass_matrix(q), lbr4p.gravity(q)
        spare = fraction * lbr4p.limits.effort_max - np.abs(g)
        np.testing.assert_allclose(a, np.clip(spare / np.diag(m), floor, cap), rtol=1e-12)
    assert (batch > floor).any() and (batch <= cap).all()


def test_the_batch_checks_its_settings(lbr4p):
    qs = np.tile(LBR4P_Q0, (2, 1))
    with pytest.raises(ParameterError, match="effort_fraction"):
        lbr4p.fast.acceleration_limits_batch(qs, 1.5, 0.5, 50.0)
    with pytest.raises(ParameterError, match="floor_rad_s2"):
        lbr4p.fast.acceleration_limits_batch(qs, 1.0, 5.0, 1.0)
