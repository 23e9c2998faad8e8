"""The phase-end limit (dqcontrol/controllers/limits/phase_end.py): ``σ + Σ_j Δ_j s_j ≤
T_tot + T`` (docs/theory.md §8.4), the room left computed by hand."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.limits.phase_end import PhaseEndLimit


@pytest.mark.parametrize(("sigma", "room"), [(1.0, 1.01), (1.95, 0.06), (3.0, 0.01)])
def test_the_row_bounds_the_phase_advance_by_the_time_left(sigma, room):
    layout = DecisionLayout(2, np.array([0.0, 0.1, 0.3]), np.array([0.1, 0.2, 0.3]))
    ctx = SimpleNamespace(trajectory=SimpleNamespace(duration=2.0), sigma=sigma, period_s=0.01)
    row = PhaseEndLimit(layout).rows(ctx)
    assert row.C.shape == (1, layout.num_vars) and row.lower[0] == -np.inf
    assert row.upper[0] == pytest.approx(room, rel=1e-15)
    z = np.random.default_rng(4).normal(size=layout.num_vars)
    s = z.reshape(3, 3)[:, 2]
    assert (row.C @ z)[0] == pytest.approx(np.dot(layout.durations_s, s), rel=1e-14)
