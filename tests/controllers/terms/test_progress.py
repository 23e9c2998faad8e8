"""The progress term (dqcontrol/controllers/terms/progress.py): its rows against the
interval weights written out (docs/theory.md §8.3), and its catch-up reference."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.terms.progress import ProgressTerm


def test_progress_rows_at_the_nominal_and_a_catching_up_reference():
    layout = DecisionLayout(2, np.array([0.0, 0.1, 0.3]), np.array([0.1, 0.2, 0.2]))
    term = ProgressTerm(layout, s_max=1.2)
    scale = np.sqrt(layout.durations_s * np.arange(3, 0, -1) / 0.5)
    for lag, s_ref in ((0.0, 1.0), (0.05, 1.1)):
        ctx = type("C", (), {"lag_s": lag})()
        res = term.residual(ctx)
        assert np.array_equal(res.b, -scale * s_ref)
        assert np.array_equal(res.blocks[:, 0, 2], -scale)


@pytest.mark.parametrize(
    ("s_max", "lag_s", "expected"),
    [
        (1.0, 0.3, 1.0),  # no catch-up allowed
        (1.2, -0.1, 1.0),  # ahead of time: nominal
        (1.2, 0.05, 1.1),  # 1 + lag / horizon (0.5 s)
        (1.2, 1.0, 1.2),  # capped at s_max
    ],
)
def test_the_reference_recovers_the_lag_over_the_horizon(s_max, lag_s, expected):
    layout = DecisionLayout(2, np.array([0.0, 0.1, 0.3]), np.array([0.1, 0.2, 0.2]))
    term = ProgressTerm(layout, s_max=s_max)
    assert term.reference(lag_s) == pytest.approx(expected, rel=1e-15)
    res = term.residual(SimpleNamespace(lag_s=lag_s))
    scale = np.sqrt(layout.durations_s * np.arange(3, 0, -1) / 0.5)
    np.testing.assert_allclose(res.b, -scale * expected, rtol=1e-15)
