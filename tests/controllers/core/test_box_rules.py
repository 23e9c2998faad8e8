"""The applied command's rule (every QP controller's): the solution's first block clipped to
its bounds and the time scaling read within ``[0, s_max]``, against numpy."""

import numpy as np
import pytest

from dqcontrol.controllers.core.box_rules import clip_solution


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("one_block", [False, True])
def test_clip_solution_is_numpys_clip(seed, one_block):
    rng = np.random.default_rng(seed)
    p, n, s_max = (1 if one_block else 5), 7, 1.2
    z = rng.normal(scale=2.0, size=p * (n + 1))
    rows = p * (n + 1) + (0 if one_block else 9)  # general rows beyond the variables
    lower, upper = rng.uniform(-1.0, 0.0, rows), rng.uniform(0.0, 1.0, rows)
    count = z.size if one_block else n  # one block, no row: every variable clipped
    expected = z.copy()
    expected[:count] = np.minimum(np.maximum(z[:count], lower[:count]), upper[:count])
    expected_s = min(max(float(z[n]), 0.0), s_max)
    s = clip_solution(z, lower, upper, n, n, s_max)
    assert s == expected_s and np.array_equal(z, expected)
    assert clip_solution(z.copy(), lower, upper, n, -1, s_max) == 1.0  # no scaling


def test_clip_solution_keeps_a_nan_for_the_caller_to_see():
    z = np.full(8, np.nan)
    s = clip_solution(z, -np.ones(8), np.ones(8), 7, 7, 1.0)
    assert np.isnan(s) and np.isnan(z).all()
