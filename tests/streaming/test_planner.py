"""The planner's period from measured step times (docs/theory.md §12.1)."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.streaming.planner import choose_plan_period


@pytest.mark.parametrize(
    ("p99_ms", "expected_ms"), [(0.2, 5.0), (1.0, 5.0), (2.4, 5.0), (2.6, 6.0), (4.6, 10.0)]
)
def test_plan_period_is_a_whole_number_of_periods_above_twice_the_p99(p99_ms, expected_ms):
    rng = np.random.default_rng(1)
    times = np.concatenate((rng.uniform(0.0, p99_ms, 990), np.full(10, p99_ms))) * 1e-3
    times[np.argmax(times)] = p99_ms * 1e-3  # the p99 is p99_ms (the top 1 % are equal)
    chosen = choose_plan_period(times, 0.001)
    assert chosen == pytest.approx(expected_ms * 1e-3)
    ratio = chosen / 0.001
    assert abs(ratio - round(ratio)) < 1e-9
    assert chosen >= max(2.0 * np.percentile(times, 99), 0.005) - 1e-12


def test_a_plan_period_is_never_shorter_than_the_floor_nor_than_the_period():
    fast = np.full(50, 1e-4)
    assert choose_plan_period(fast, 0.001) == pytest.approx(0.005)
    assert choose_plan_period(fast, 0.01) == pytest.approx(0.01)  # one period
    assert choose_plan_period(fast, 0.001, floor_s=0.0) == pytest.approx(0.001)
