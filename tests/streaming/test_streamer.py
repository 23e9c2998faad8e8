"""dqcontrol/streaming/streamer.py: the streamer against seeded random plans: every command
within the velocity, acceleration and jerk limits, positions equal to the plan's, late
plans refused, the play-out a stop at rest on the plan's path (docs/theory.md §12.2–12.3)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dqcontrol.streaming.plan import Plan
from dqcontrol.streaming.streamer import Streamer
from dqcontrol.streaming.tracker import JerkLimitedTracker

T = 0.001
N_JOINTS = 3
V_MAX, A_MAX, J_MAX = 2.0, 10.0, 5000.0


def _random_plan(rng, start_k: int, q0, sigma0: float, scale: float, grid=False) -> Plan:
    p = 6
    durations = np.concatenate(([0.01], rng.uniform(0.02, 0.2, p - 1)))
    if grid:  # breakpoints on the stream's samples
        durations = np.round(durations / T) * T
    qd = rng.uniform(-scale, scale, (p, N_JOINTS))
    return Plan(start_k + 1, start_k, start_k * T, np.array(q0), sigma0, durations, qd,
                rng.uniform(0, 1, p))  # fmt: skip


def _feasible_plan(rng) -> Plan:
    """A plan whose interval velocities change by at most ``ā`` times the time between
    interval centres (the controller's acceleration rows)."""
    durations = np.round(np.concatenate(([0.01], rng.uniform(0.02, 0.2, 5))) / T) * T
    centres = 0.5 * (durations[1:] + durations[:-1])
    steps = rng.uniform(-1, 1, (5, N_JOINTS)) * A_MAX * centres[:, None]
    first = rng.uniform(-1, 1, (1, N_JOINTS)) * A_MAX * durations[0]
    qd = np.cumsum(np.vstack((first, steps)), axis=0)
    return Plan(1, 0, 0.0, np.zeros(N_JOINTS), 0.0, durations, qd, np.ones(6))


def _limits() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return (np.full(N_JOINTS, V_MAX), np.full(N_JOINTS, A_MAX), np.full(N_JOINTS, J_MAX))


def _check_within(u: np.ndarray) -> None:
    a = np.diff(np.vstack((np.zeros(N_JOINTS), u)), axis=0) / T
    j = np.diff(np.vstack((np.zeros(N_JOINTS), a)), axis=0) / T
    tol = 1e-9
    assert np.all(np.abs(u) <= V_MAX * (1 + tol))
    assert np.all(np.abs(a) <= A_MAX * (1 + tol))
    assert np.all(np.abs(j) <= J_MAX * (1 + tol))


@given(st.integers(0, 2**32 - 1), st.lists(st.integers(5, 400), min_size=1, max_size=5))
def test_every_streamed_command_is_within_every_limit(seed, gaps):
    rng = np.random.default_rng(seed)
    streamer = Streamer(JerkLimitedTracker(*_limits(), T), 0.02, patience_k=10_000)
    streamer.restart(np.zeros(N_JOINTS), 0.0)
    switches = set(np.cumsum(gaps).tolist())
    streamer.offer(_random_plan(rng, 0, np.zeros(N_JOINTS), 0.0, 2.5))  # beyond v̄ too
    out = []
    for k in range(int(max(switches)) + 300):
        if k in switches:
            streamer.offer(_random_plan(rng, k, streamer.q, 0.0, 2.5))
        out.append(streamer.step().u)
    _check_within(np.array(out))


def test_unbounded_stream_integrates_to_the_plan_states():
    rng = np.random.default_rng(7)
    inf = np.full(N_JOINTS, np.inf)
    streamer = Streamer(JerkLimitedTracker(np.full(N_JOINTS, 5.0), inf, inf, T), 0.02, 10_000)
    q0 = rng.uniform(-1, 1, N_JOINTS)
    streamer.restart(q0, 0.0)
    plan = _random_plan(rng, 0, q0, 0.0, 1.0, grid=True)
    streamer.offer(plan)
    q = q0.copy()
    ends_k = np.round(plan.ends_s / T).astype(int)
    states = plan.states()
    for k in range(ends_k[-1] + 1):
        if k in ends_k:  # a breakpoint (or the last state)
            np.testing.assert_allclose(q, states[list(ends_k).index(k)], atol=1e-12)
        q = q + T * streamer.step().u


def test_bounded_stream_stays_within_its_tolerance_of_the_plan():
    """The blend's stated tolerance (docs/theory.md §12.2): ``v̄ (v̄/ā + ā/j̄)``, the
    distance of the longest transition, and the plan's end reached within 1e-6 rad."""
    rng = np.random.default_rng(11)
    streamer = Streamer(JerkLimitedTracker(*_limits(), T), 0.02, 10_000)
    streamer.restart(np.zeros(N_JOINTS), 0.0)
    plan = _feasible_plan(rng)
    streamer.offer(plan)
    jumps = np.abs(np.diff(np.vstack((np.zeros(N_JOINTS), plan.qd, np.zeros(N_JOINTS))), axis=0))
    tol = float(np.max(jumps * (jumps / A_MAX + A_MAX / J_MAX)))
    q, tau = np.zeros(N_JOINTS), 0.0
    for _ in range(int(round(plan.duration_s / T)) + 2000):
        assert np.max(np.abs(q - plan.position(tau))) <= tol
        q = q + T * streamer.step().u
        tau += T
    np.testing.assert_allclose(q, plan.position(plan.duration_s), atol=1e-6)


def test_a_plan_offered_after_its_start_is_refused_and_counted():
    rng = np.random.default_rng(5)
    streamer = Streamer(JerkLimitedTracker(*_limits(), T), 0.02, 10_000)
    streamer.restart(np.zeros(N_JOINTS), 0.0)
    first = _random_plan(rng, 0, np.zeros(N_JOINTS), 0.0, 1.0)
    streamer.offer(first)
    for _ in range(20):
        streamer.step()
    late = _random_plan(rng, 10, streamer.q, 0.0, 1.0)
    assert not streamer.offer(late)
    assert streamer.refused == 1
    assert streamer.step().plan_id == first.plan_id


def test_without_new_plans_the_last_is_played_out_to_rest_on_its_path():
    rng = np.random.default_rng(9)
    streamer = Streamer(JerkLimitedTracker(*_limits(), T), 0.02, patience_k=20)
    streamer.restart(np.zeros(N_JOINTS), 0.0)
    plan = _random_plan(rng, 0, np.zeros(N_JOINTS), 0.0, 0.5)
    streamer.offer(plan)
    out, modes = [], []
    for _ in range(int(round(plan.duration_s / T)) * 3):
        sample = streamer.step()
        out.append(sample.u)
        modes.append(sample.mode)
    _check_within(np.array(out))
    assert modes[-1] == "stopped" and "no new plan" in streamer.playout_note
    assert streamer.tau_s < plan.duration_s  # it stopped within the plan
    np.testing.assert_allclose(streamer.q, plan.position(streamer.tau_s), atol=1e-6)


def test_without_a_plan_a_taken_over_command_and_phase_rate_are_held():
    """After :meth:`Streamer.take_over` the stream holds the other controller's command
    (its acceleration brought to zero within the jerk bound) and phase rate, as the
    projection of the first plan's start assumes."""
    streamer = Streamer(JerkLimitedTracker(*_limits(), T), 0.02, patience_k=10)
    u0, a0 = np.array([1.0, -0.5, 0.2]), np.array([3.0, 0.0, -2.0])
    streamer.take_over(np.array([0.1, 0.2, 0.3]), 0.4, u0, a0, 0.8)
    commands = np.array([streamer.step().u for _ in range(20)])
    a = np.diff(np.vstack((u0 - T * a0, u0, commands)), axis=0) / T
    assert np.all(np.abs(np.diff(a, axis=0)) <= J_MAX * T * (1 + 1e-9))  # jerk kept
    assert np.allclose(a[-5:], 0.0) and np.all(np.abs(commands[-1] - u0) < 0.01)
    assert streamer.sigma0 == pytest.approx(0.4 + 20 * T * 0.8)
    assert streamer.k == 20


def test_a_followed_command_sets_the_tracker_the_positions_and_the_phase():
    streamer = Streamer(JerkLimitedTracker(*_limits(), T), 0.02, patience_k=10)
    q0, u0 = np.array([0.1, 0.2, 0.3]), np.array([1.0, -0.5, 0.2])
    streamer.take_over(q0, 0.4, u0, np.zeros(N_JOINTS), 1.0)
    u1 = u0 + np.array([0.002, 0.0, -0.001])
    streamer.follow(u1, 0.4 + 0.9 * T)
    assert np.array_equal(streamer.tracker.u, u1)
    assert np.allclose(streamer.tracker.a, (u1 - u0) / T)
    assert np.allclose(streamer.q, q0 + T * u1)
    assert streamer.s_hold == pytest.approx(0.9) and streamer.k == 1
    assert streamer.step().sigma == pytest.approx(0.4 + 0.9 * T)  # held from there


def test_from_rest_without_a_plan_the_command_stays_exactly_zero():
    streamer = Streamer(JerkLimitedTracker(*_limits(), T), 0.02, patience_k=10)
    streamer.restart(np.zeros(N_JOINTS), 0.3)
    samples = [streamer.step() for _ in range(5)]
    assert all(np.all(s.u == 0.0) and s.sigma == s.sigma_next == 0.3 for s in samples)
