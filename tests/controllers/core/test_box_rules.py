"""The box rules of :mod:`dqcontrol.controllers.core.box_rules`: the applied command's rule
(the solution's first block clipped to its bounds, the time scaling read within
``[0, s_max]``) against numpy, the joint-box kernels against ``bounds._vp_box``, and the
compiled braking constants against ``bounds.braking_constants``."""

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


@pytest.mark.parametrize("braking", [True, False])
def test_vp_boxes_equal_numpy_vp_box_bit_for_bit(braking):
    """The joint-box kernels (``joint_box.applied_box_into`` on ``q`` for instant 0,
    ``predicted_boxes_into`` on the clipped predictions for the others) against
    ``bounds._vp_box``: random states with joints beyond their limits, per-instant braking
    constants."""
    from dqcontrol.controllers.core.bounds import _vp_box, braking_constants
    from dqcontrol.controllers.core.box_rules import applied_box_into, predicted_boxes_into

    rng = np.random.default_rng(17 + braking)
    beyond = 0
    for _ in range(300):
        p, n = int(rng.integers(1, 12)), int(rng.integers(1, 9))
        q_min = rng.uniform(-3.0, -0.5, n)
        q_max = rng.uniform(0.5, 3.0, n)
        span = q_max - q_min
        q = q_min + rng.uniform(-0.02, 1.02, n) * span  # sometimes beyond a limit
        q_hat = q_min + rng.uniform(-0.1, 1.1, (p, n)) * span
        q_hat[0] = q
        qd_max = rng.uniform(0.5, 8.0, n)
        period = float(rng.choice([1e-3, 0.01, 0.05]))
        a_max = rng.uniform(0.5, 50.0, (p, n))
        brake = braking_constants(a_max, period)
        q_box = np.minimum(np.maximum(q_hat, q_min), q_max)
        q_box[0] = q
        lo_ref, hi_ref = _vp_box(q_box, q_min, q_max, qd_max, period, brake if braking else None)
        lower, upper = np.full(p * n, -np.inf), np.full(p * n, np.inf)
        index = np.arange(p * n).reshape(p, n)
        stacked = np.array(brake)
        applied_box_into(
            q, q_min, q_max, qd_max, period, braking, stacked[:, 0], index[0], lower, upper
        )
        predicted_boxes_into(
            q_hat, q_min, q_max, qd_max, period, braking, stacked, index, lower, upper
        )
        np.testing.assert_array_equal(lower.reshape(p, n), lo_ref)
        np.testing.assert_array_equal(upper.reshape(p, n), hi_ref)
        beyond += bool(np.any((q < q_min) | (q > q_max)))
    assert beyond > 20  # the beyond-a-limit rule was exercised


def test_compiled_braking_constants_are_numpys():
    """The braking rows ``[a T; 2 a; (a T)²]`` from a moving ``a_max``, bit for bit."""
    from dqcontrol.controllers.core.bounds import braking_constants
    from dqcontrol.controllers.core.box_rules import braking_rows

    rng = np.random.default_rng(31)
    a_max = rng.uniform(0.5, 50.0, size=(6, 7))
    assert np.array_equal(braking_rows(a_max[0], 1e-3), np.array(braking_constants(a_max[0], 1e-3)))
