"""The velocity limit (dqcontrol/controllers/limits/velocity.py): ``|qd_i| ≤ qd_max`` on
every block's joint velocities and nothing on the scalings (docs/theory.md §5)."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.limits.velocity import VelocityLimit


def test_every_block_gets_the_same_symmetric_box():
    layout = DecisionLayout(3, np.array([0.0, 0.1, 0.3]), np.array([0.1, 0.2, 0.2]))
    qd_max = np.array([1.0, 2.0, 2.5])
    rows = VelocityLimit(layout, qd_max).rows(None)
    assert rows.name == "velocity" and not rows.hard
    idx = np.asarray(rows.index)
    np.testing.assert_array_equal(idx, [0, 1, 2, 4, 5, 6, 8, 9, 10])  # every 4th is an s
    np.testing.assert_array_equal(rows.upper, np.tile(qd_max, 3))
    np.testing.assert_array_equal(rows.lower, -np.tile(qd_max, 3))
    assert np.intersect1d(idx, layout.s_index()).size == 0
