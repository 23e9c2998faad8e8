"""The limit contract (dqcontrol/controllers/limits/limit.py): ``rows`` is the one method to
write; a limit is soft, not relaxable, and offers no fast path unless it says so
(docs/theory.md §7.3)."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.problem import Bounds
from dqcontrol.controllers.limits.limit import Limit


class FirstAtMostOne(Limit):
    """The smallest limit: ``z_0 ≤ 1``."""

    name = "first_at_most_one"

    def rows(self, ctx):
        return Bounds(self.name, np.array([0]), np.array([-np.inf]), np.array([1.0]))


def test_a_limit_without_rows_cannot_be_made():
    class NoRows(Limit):
        pass

    with pytest.raises(TypeError, match="rows"):
        NoRows()


def test_the_defaults_are_soft_kept_and_without_fast_paths():
    limit = FirstAtMostOne()
    assert not limit.hard and not limit.relaxable
    assert Limit.name == "limit"
    lower, upper, conflict = np.full(3, -5.0), np.full(3, 5.0), np.zeros(3, dtype=bool)
    assert limit.tighten(None, lower, upper, conflict) is False
    assert limit.row_bounds(None, lower, upper) is False
    # the arrays are left as they were
    assert (lower == -5.0).all() and (upper == 5.0).all() and not conflict.any()
    assert limit.rows(None).upper[0] == 1.0
