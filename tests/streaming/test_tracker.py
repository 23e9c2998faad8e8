"""dqcontrol/streaming/tracker.py: the reachable acceleration against its definition (the
velocity gained while the acceleration is brought to zero at the jerk bound), and the
tracker's commands within the limits by finite differences."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from dqcontrol.streaming.tracker import JerkLimitedTracker, reachable_acceleration

T = 0.001


def _gain(a: float, jerk_step: float) -> float:
    """``D(a)`` by its definition: the velocity gained while ``a`` is brought to zero."""
    total, x = 0.0, a
    while x > 0.0:
        total += T * x
        x -= jerk_step
    return total


@given(st.floats(0.0, 5.0), st.floats(0.01, 20.0))
def test_reachable_acceleration_is_the_largest_within_the_gap(gap, jerk_step):
    a = float(reachable_acceleration(np.array([gap]), np.array([jerk_step]), T)[0])
    assert _gain(a, jerk_step) <= gap + 1e-9
    assert _gain(a * (1 + 1e-6) + 1e-9, jerk_step) > gap - 1e-9


def test_the_tracker_reaches_its_target_within_the_limits():
    rng = np.random.default_rng(17)
    v_max, a_max, j_max = np.array([2.0, 1.0, 3.0]), np.array([10.0, 5.0, 20.0]), 5000.0
    tracker = JerkLimitedTracker(v_max, a_max, np.full(3, j_max), T)
    tracker.restart(np.zeros(3), np.zeros(3))
    targets = [rng.uniform(-3.0, 3.0, 3) for _ in range(3)]  # beyond v̄ too
    out = []
    for target in targets:
        for _ in range(1500):
            out.append(tracker.step(target).copy())
        np.testing.assert_allclose(out[-1], np.clip(target, -v_max, v_max), atol=1e-9)
    u = np.array(out)
    a = np.diff(np.vstack((np.zeros(3), u)), axis=0) / T
    j = np.diff(np.vstack((np.zeros(3), a)), axis=0) / T
    assert np.all(np.abs(u) <= v_max * (1 + 1e-9))
    assert np.all(np.abs(a) <= a_max * (1 + 1e-9))
    assert np.all(np.abs(j) <= j_max * (1 + 1e-9))


def test_a_copy_goes_on_alone():
    tracker = JerkLimitedTracker(np.full(2, 1.0), np.full(2, 5.0), np.full(2, 1000.0), T)
    tracker.restart(np.zeros(2), np.zeros(2))
    tracker.step(np.ones(2))
    twin = tracker.copy()
    a = [tracker.step(np.ones(2)).copy() for _ in range(5)]
    b = [twin.step(np.ones(2)).copy() for _ in range(5)]
    np.testing.assert_array_equal(a, b)
    u, acc = tracker.u.copy(), tracker.a.copy()
    twin.step(-np.ones(2))
    np.testing.assert_array_equal(tracker.u, u)
    np.testing.assert_array_equal(tracker.a, acc)
