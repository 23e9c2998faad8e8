"""The joint velocity bounds of :mod:`dqcontrol.controllers.core.bounds` (docs/theory.md §5)
against a numpy reference written one side at a time and hand-computed values, and over random
limits and states (Hypothesis): the fallback always admissible, admissible commands never
leading out of the limits."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dqcontrol.controllers.core.bounds import (
    Box,
    braking_constants,
    braking_speed,
    command_box,
    intersect_acceleration,
    safe_command,
    velocity_position_box,
)


def _reference_box(q, q_min, q_max, qd_max, period_s, a_max):
    """The bounds as first written (one side at a time), the oracle of the stacked pass."""
    lo = np.maximum(-qd_max, (q_min - q) / period_s)
    hi = np.minimum(qd_max, (q_max - q) / period_s)
    if a_max is not None:
        hi = np.minimum(hi, braking_speed(q_max - q, a_max, period_s))
        lo = np.maximum(lo, -braking_speed(q - q_min, a_max, period_s))
    hi = np.maximum(hi, np.minimum(lo, qd_max))
    lo = np.minimum(lo, hi)
    return lo, hi


@pytest.mark.parametrize("braking", [True, False])
@pytest.mark.parametrize("shape", [(7,), (10, 7)])
def test_stacked_bounds_equal_the_reference(braking, shape):
    rng = np.random.default_rng(7)
    q_min, q_max = -np.full(7, 2.9), np.full(7, 2.9)
    qd_max = rng.uniform(1.0, 3.0, 7)
    for _ in range(50):
        q = rng.uniform(-3.2, 3.2, shape)  # some beyond the limits
        a = rng.uniform(0.5, 40.0, shape) if braking else None
        for period in (0.001, 0.05):
            got = velocity_position_box(q, q_min, q_max, qd_max, period, a)
            want = _reference_box(q, q_min, q_max, qd_max, period, a)
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])
    q = rng.uniform(-3.0, 3.0, 7)
    box = command_box(q, np.zeros(7), q_min, q_max, qd_max, np.full(7, 10.0), 0.001)
    lo, hi = _reference_box(q, q_min, q_max, qd_max, 0.001, np.full(7, 10.0))
    want = intersect_acceleration(lo, hi, np.zeros(7), np.full(7, 0.01))
    np.testing.assert_array_equal(box.lower, want.lower)
    np.testing.assert_array_equal(box.upper, want.upper)


def test_braking_speed_stops_within_the_distance():
    """One period at ``v`` then braking at ``a`` covers the distance exactly; no distance
    (or a negative one) gives no speed."""
    rng = np.random.default_rng(21)
    distance = rng.uniform(0.0, 2.0, 50)
    a_max, period = rng.uniform(0.5, 40.0, 50), 0.004
    v = braking_speed(distance, a_max, period)
    assert np.all(v >= 0.0)
    np.testing.assert_allclose(period * v + v * v / (2.0 * a_max), distance, rtol=1e-10, atol=1e-15)
    np.testing.assert_array_equal(braking_speed(np.array([0.0, -0.3]), np.ones(2), period), 0.0)
    at, two_a, at2 = braking_constants(a_max, period)
    np.testing.assert_array_equal(at, a_max * period)
    np.testing.assert_array_equal(two_a, 2.0 * a_max)
    np.testing.assert_array_equal(at2, (a_max * period) ** 2)


def test_a_joint_beyond_its_limit_may_only_move_back():
    q_min, q_max, qd_max = np.full(2, -1.0), np.full(2, 1.0), np.full(2, 0.5)
    q = np.array([1.2, -1.01])  # beyond the upper limit, just beyond the lower one
    lo, hi = velocity_position_box(q, q_min, q_max, qd_max, 0.1, None)
    # the first must return faster (2 rad/s) than allowed: the velocity bound wins
    np.testing.assert_allclose(lo, [-0.5, 0.1], rtol=1e-12)
    np.testing.assert_allclose(hi, [-0.5, 0.5], rtol=1e-12)


def test_intersect_acceleration_keeps_the_acceleration_bound_in_a_conflict():
    lo_vp, hi_vp = np.array([-1.0, -1.0, 0.5]), np.array([1.0, -0.5, 1.0])
    qd_prev, step = np.array([0.2, 0.0, 0.0]), np.full(3, 0.1)
    box = intersect_acceleration(lo_vp, hi_vp, qd_prev, step)
    # joint 0 meets both; joint 1 brakes down to -0.1, joint 2 speeds up to 0.1 at most
    np.testing.assert_allclose(box.lower, [0.1, -0.1, 0.1])
    np.testing.assert_allclose(box.upper, [0.3, -0.1, 0.1])
    np.testing.assert_array_equal(box.conflict, [False, True, True])


def test_box_contains_projects_and_gives_the_safe_command():
    box = Box(np.array([-1.0, 0.2, -0.5]), np.array([1.0, 0.4, -0.1]), np.zeros(3, bool))
    assert box.contains(np.array([0.0, 0.3, -0.2]))
    assert not box.contains(np.array([0.0, 0.41, -0.2]))
    assert box.contains(np.array([0.0, 0.41, -0.2]), tol=0.02)
    np.testing.assert_array_equal(box.project(np.array([2.0, 0.0, -0.3])), [1.0, 0.2, -0.3])
    np.testing.assert_array_equal(safe_command(box), [0.0, 0.2, -0.1])


def test_command_box_without_braking_is_the_plain_position_bound():
    rng = np.random.default_rng(22)
    q_min, q_max = np.full(7, -2.0), np.full(7, 2.0)
    q, qd_prev = rng.uniform(-1.9, 1.9, 7), np.zeros(7)
    qd_max, a_max = np.full(7, 1.0), np.full(7, 5.0)
    box = command_box(q, qd_prev, q_min, q_max, qd_max, a_max, 0.01, braking_aware=False)
    lo = np.maximum(-qd_max, (q_min - q) / 0.01)
    hi = np.minimum(qd_max, (q_max - q) / 0.01)
    want = intersect_acceleration(lo, hi, qd_prev, 0.01 * a_max)
    np.testing.assert_array_equal(box.lower, want.lower)
    np.testing.assert_array_equal(box.upper, want.upper)


#: The tolerance of the property tests [rad/s].
TOL = 1e-9


@st.composite
def joint_setups(draw, n=3):
    """Random limits, period, velocity and acceleration bounds for ``n`` joints."""
    period = draw(st.sampled_from([0.001, 0.005, 0.02, 0.05, 0.1]))
    lo = np.array(draw(st.lists(st.floats(-3.0, 0.5), min_size=n, max_size=n)))
    width = np.array(draw(st.lists(st.floats(0.05, 4.0), min_size=n, max_size=n)))
    qd_max = np.array(draw(st.lists(st.floats(0.1, 8.0), min_size=n, max_size=n)))
    a_max = np.array(draw(st.lists(st.floats(0.5, 60.0), min_size=n, max_size=n)))
    return period, lo, lo + width, qd_max, a_max


@settings(max_examples=200)
@given(setup=joint_setups(), data=st.data())
def test_the_fallback_is_always_admissible(setup, data):
    """From any state (even beyond a limit, even moving faster than allowed), the fallback
    is in the box and respects the acceleration bound; inside the limits it slows every joint
    down, beyond a limit it heads back."""
    period, q_min, q_max, qd_max, a_max = setup
    n = q_min.size
    span = q_max - q_min
    q = q_min + span * np.array(data.draw(st.lists(st.floats(-0.2, 1.2), min_size=n, max_size=n)))
    qd_prev = qd_max * np.array(data.draw(st.lists(st.floats(-1.5, 1.5), min_size=n, max_size=n)))
    box = command_box(q, qd_prev, q_min, q_max, qd_max, a_max, period)
    qd = safe_command(box)
    assert np.all(box.lower <= box.upper + TOL)  # never empty
    assert box.contains(qd, TOL)
    assert np.all(np.abs(qd - qd_prev) <= period * a_max + TOL)  # acceleration: always
    inside = (q >= q_min) & (q <= q_max)
    # inside the limits it never speeds a joint up; beyond one it only heads back
    assert np.all(np.abs(qd[inside]) <= np.abs(qd_prev[inside]) + TOL)
    below, above = q < q_min, q > q_max
    assert np.all((qd[below] >= qd_prev[below] - TOL) | (qd[below] >= -TOL))
    assert np.all((qd[above] <= qd_prev[above] + TOL) | (qd[above] <= TOL))
    ok = ~box.conflict
    # where the bounds do not conflict, the fallback is also within velocity and position
    assert np.all(np.abs(qd[ok]) <= qd_max[ok] + TOL)
    inner = ok & inside
    assert np.all(q[inner] + period * qd[inner] <= q_max[inner] + TOL)
    assert np.all(q[inner] + period * qd[inner] >= q_min[inner] - TOL)
    # it is the admissible command closest to standing still
    assert np.all((qd == 0.0) | (qd == box.lower) | (qd == box.upper))


@settings(max_examples=100)
@given(setup=joint_setups(), data=st.data(), steps=st.integers(5, 80))
def test_admissible_commands_never_lead_out_of_the_limits(setup, data, steps):
    """Start at rest inside the limits and apply *any* command of each period's box (here
    a random one, or the extreme towards a limit): the joints never leave their limits and
    the bounds never conflict — what the braking-aware position bound is for."""
    period, q_min, q_max, qd_max, a_max = setup
    n = q_min.size
    q = q_min + (q_max - q_min) * np.array(
        data.draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n))
    )
    qd_prev = np.zeros(n)
    for _ in range(steps):
        box = command_box(q, qd_prev, q_min, q_max, qd_max, a_max, period)
        assert not box.conflict.any()
        pick = data.draw(st.sampled_from(["random", "upper", "lower"]))
        if pick == "random":
            frac = np.array(data.draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n)))
            qd = box.lower + frac * (box.upper - box.lower)
        else:
            qd = box.upper if pick == "upper" else box.lower
        q = q + period * qd
        qd_prev = qd
        assert np.all(q <= q_max + 1e-9) and np.all(q >= q_min - 1e-9)
