"""Standing still while stalled (dqcontrol/controllers/path_following/stillness.py): the
applied block becomes the point of its bounds closest to zero with ``s = 0`` (against
``np.clip``) unless the plan progresses; fallbacks and missing solutions are left alone."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.controllers.core.levels import LevelsResult
from dqcontrol.controllers.core.problem import Solution
from dqcontrol.controllers.path_following.stillness import hold_still
from dqcontrol.controllers.qp_controller import Solved

N = 3


def _solved(z, lower, upper, failed_level=None) -> Solved:
    """A solve with the decision ``z`` (the applied block first, ``s`` at index ``N``); the
    problem stands in for a step problem by its bounds alone."""
    x = None if z is None else np.asarray(z, dtype=float)
    solution = Solution(x is not None, "solved", x=x)
    result = LevelsResult(solution, (solution,), failed_level)
    problem = SimpleNamespace(lower=lower, upper=upper)
    return Solved(problem, result, "", 0, 0.0)  # type: ignore[arg-type]


@pytest.mark.parametrize("seed", range(5))
def test_a_stalled_plan_is_replaced_by_the_bounds_point_nearest_rest(seed):
    rng = np.random.default_rng(seed)
    z = rng.normal(size=2 * (N + 1))
    z[N] = 0.01  # below the threshold: no progress
    later = z[N + 1 :].copy()
    lower = np.concatenate([rng.uniform(-1.0, 0.5, N), [0.0]])
    upper = np.concatenate([lower[:N] + rng.uniform(0.0, 1.0, N), [1.0]])
    solved = _solved(z, lower, upper)
    assert hold_still(solved, N, 0.05)
    x = solved.result.solution.x
    np.testing.assert_array_equal(x[:N], np.clip(np.zeros(N), lower[:N], upper[:N]))
    assert x[N] == 0.0
    np.testing.assert_array_equal(x[N + 1 :], later)  # the later blocks are kept


def test_a_progressing_plan_is_applied_as_it_is():
    z = np.array([0.3, -0.2, 0.1, 0.05, 1.0, 1.0, 1.0, 1.0])
    solved = _solved(z.copy(), -np.ones(8), np.ones(8))
    assert not hold_still(solved, N, 0.05)  # s = 0.05 reaches the threshold
    np.testing.assert_array_equal(solved.result.solution.x, z)


def test_a_fallback_or_a_step_without_a_solution_is_left_alone():
    z = np.array([0.5, -0.5, 2.0, 0.0])  # s = 0 but the first level failed
    assert not hold_still(_solved(z, -np.ones(4), np.ones(4), failed_level=0), N, 0.05)
    np.testing.assert_array_equal(z, [0.5, -0.5, 2.0, 0.0])
    assert not hold_still(_solved(None, -np.ones(4), np.ones(4)), N, 0.05)
    assert not hold_still(_solved(z, None, None), N, 0.05)
