"""dqcontrol/streaming/planner.py: the planner's period from measured step times, and the
projection of a measurement to a plan's start against the streamer's own commands and a
fine integration of the servo's first-order lag (docs/theory.md §12.1, §8.7)."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.streaming.plan import Plan
from dqcontrol.streaming.planner import choose_plan_period, project
from dqcontrol.streaming.streamer import Streamer
from dqcontrol.streaming.tracker import JerkLimitedTracker

T = 0.001


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


def _streaming(seed: int) -> Streamer:
    """A streamer 5 samples into a seeded random plan of 3 joints."""
    rng = np.random.default_rng(seed)
    inf = np.full(3, np.inf)
    streamer = Streamer(JerkLimitedTracker(np.full(3, 2.0), np.full(3, 10.0), inf, T), 0.02, 10_000)
    streamer.restart(np.zeros(3), 0.3)
    durations = np.array([0.005, 0.01, 0.02])
    streamer.offer(Plan(1, 0, 0.0, np.zeros(3), 0.3, durations, rng.uniform(-1, 1, (3, 3)),
                        np.full(3, 0.8)))  # fmt: skip
    for _ in range(5):
        streamer.step()
    return streamer


def test_without_a_lead_the_request_is_the_measurement():
    streamer = _streaming(1)
    q, qd = np.array([0.1, 0.2, 0.3]), np.array([0.0, 0.5, -0.5])
    request = project(streamer, q, qd, lead_k=0, plan_id=4)
    assert (request.plan_id, request.start_k, request.made_s) == (4, 5, pytest.approx(5 * T))
    np.testing.assert_array_equal(request.q, q)
    np.testing.assert_array_equal(request.qd, qd)
    np.testing.assert_array_equal(request.qd_prev, streamer.tracker.u)
    assert request.sigma == pytest.approx(streamer.plan.phase(streamer.tau_s))


def test_a_lead_adds_the_committed_commands_and_leaves_the_streamer_alone():
    streamer = _streaming(2)
    twin = streamer.copy()
    commands = [twin.step() for _ in range(7)]
    k_before, q_before = streamer.k, streamer.q.copy()
    q = np.array([0.1, 0.2, 0.3])
    request = project(streamer, q, np.full(3, 9.0), lead_k=7, plan_id=2)
    assert streamer.k == k_before and np.array_equal(streamer.q, q_before)
    np.testing.assert_allclose(request.q, q + T * sum(c.u for c in commands), atol=1e-15)
    assert request.qd is None and request.start_k == k_before + 7
    assert request.made_s == pytest.approx(k_before * T)
    np.testing.assert_array_equal(request.qd_prev, commands[-1].u)
    assert request.sigma == commands[-1].sigma_next


def test_behind_a_servo_lag_the_arm_follows_the_commands_as_a_first_order_lag():
    streamer = _streaming(3)
    twin = streamer.copy()
    commands = [twin.step().u for _ in range(6)]
    lag_s, q, v = 0.004, np.array([0.1, 0.2, 0.3]), np.array([0.4, -0.3, 0.0])
    request = project(streamer, q, v, lead_k=6, plan_id=3, lag_s=lag_s)
    substeps, fine_q, fine_v = 2000, q.copy(), v.copy()  # v' = (u - v) / lag, q' = v
    h = T / substeps
    for u in commands:
        for _ in range(substeps):
            fine_v_next = fine_v + h * (u - fine_v) / lag_s
            fine_q += 0.5 * h * (fine_v + fine_v_next)
            fine_v = fine_v_next
    np.testing.assert_allclose(request.qd, fine_v, atol=1e-3)
    np.testing.assert_allclose(request.q, fine_q, atol=1e-6)
