"""The jerk limit (docs/theory.md §8.11): its rows against second differences formed with
numpy, the stops it plans against a simulation, and closed kinematic loops in which no
command leaves a limit and every next problem stays feasible."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dqcontrol.controllers import LocalController, PathFollowingController, ProportionalController
from dqcontrol.controllers.limits.jerk import JerkLimit, applied_jerk_box
from dqcontrol.controllers.limits.predicted_position import PredictedPositionLimit
from dqcontrol.controllers.prediction.consistent import ConsistentPrediction, interval_breakpoints
from dqcontrol.errors import ParameterError
from dqcontrol.model import PANDA_Q0
from dqcontrol.trajectories import Circle

#: Franka Panda (libfranka's rate limiter).
PANDA_V = np.array([2.175] * 4 + [2.61] * 3)
PANDA_A = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
PANDA_J = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0])
RTOL = 1e-9


def _ctx(q, u1, u2, a_max):
    return SimpleNamespace(q=q, qd_prev=u1, qd_before_prev=u2, a_max=a_max)


@pytest.mark.parametrize("seed", range(4))
def test_horizon_rows_are_second_differences_of_the_plan(seed):
    """Each horizon row, centred and divided by its half-width, is the jerk between the
    intervals' centres over ``j̄``, with the two applied commands as the intervals before."""
    rng = np.random.default_rng(seed)
    p, n, period = 6, 3, 0.01
    breaks = interval_breakpoints(p, 0.5, period)
    layout = ConsistentPrediction(breaks, n, period).layout
    durations = np.diff(breaks)
    coupling = 0.5 * (durations[1:] + durations[:-1])
    jerk = rng.uniform(50.0, 500.0, n)
    limit = JerkLimit(layout, period, jerk, np.full(n, 2.0), -np.full(n, 3.0), np.full(n, 3.0),
                      coupling)  # fmt: skip
    u1 = rng.normal(size=n)
    u2 = u1 - period * rng.uniform(-10.0, 10.0, n)  # the last acceleration within 10 rad/s²
    rows = {r.name: r for r in limit.rows(_ctx(np.zeros(n), u1, u2, np.full((p, n), 10.0)))}
    horizon = rows["jerk_horizon"]
    z = rng.normal(size=layout.num_vars)
    qd = layout.split(z)[0]
    # numpy: velocities at the interval centres, two earlier intervals of length T
    centres = np.concatenate(([-1.5 * period, -0.5 * period], breaks[:-1] + 0.5 * durations))
    v = np.vstack((u2, u1, qd))
    acc = np.diff(v, axis=0) / np.diff(centres)[:, None]
    mids = 0.5 * (centres[1:] + centres[:-1])
    jerks = np.diff(acc, axis=0) / np.diff(mids)[:, None]  # the applied one first
    centre = 0.5 * (horizon.lower + horizon.upper)
    half = 0.5 * (horizon.upper - horizon.lower)
    got = ((horizon.C @ z - centre) / half).reshape(p - 1, n)
    np.testing.assert_allclose(got, jerks[1:] / jerk, rtol=1e-9, atol=1e-9)
    # the applied command's hard bound: the jerk interval within the acceleration's
    applied = rows["jerk_applied"]
    second = 2.0 * u1 - u2
    a_t = 10.0 * period
    assert np.all(applied.lower >= np.maximum(second - jerk * period**2, u1 - a_t) - 1e-12)
    assert np.all(applied.upper <= np.minimum(second + jerk * period**2, u1 + a_t) + 1e-12)
    assert applied.hard


def _ramp_drop(a_new: float, j: float, period: float) -> float:
    """Velocity change [rad/s] of applying ``a_new`` for one period and then bringing the
    acceleration back to 0 at ``j T`` per period."""
    if a_new >= 0.0:
        return period * a_new
    m = int(np.ceil(-a_new / (j * period))) - 1  # periods still below 0 after this one
    return period * (a_new + m * a_new + j * period * m * (m + 1) / 2.0)


def _stop_distance(v: float, acc: float, b: float, j: float, period: float) -> float:
    """Distance [rad] of a discrete stop from ``v > 0`` (``acc`` the last acceleration):
    each period the acceleration moves by at most ``j T`` and stays above ``-b``, as low as
    lets it come back to 0 before the velocity reverses (a simulation, not the limit's
    formula)."""
    dist, a = 0.0, acc
    while v > j * period * period:
        lo, hi = max(a - j * period, -b), a + j * period
        if v + _ramp_drop(lo, j, period) < 0.0:
            for _ in range(60):  # the lowest acceleration that still ends at rest
                mid = 0.5 * (lo + hi)
                lo, hi = (lo, mid) if v + _ramp_drop(mid, j, period) >= 0.0 else (mid, hi)
            lo = hi
        a = lo
        v += period * a
        dist += period * max(v, 0.0)
    return dist + period * max(v, 0.0)


@pytest.mark.parametrize("seed", range(6))
def test_braking_bound_leaves_room_for_a_jerk_limited_stop(seed):
    """At the soft braking bound, with the acceleration at its bound towards the limit, the
    simulated jerk-limited stop ends before the limit."""
    rng = np.random.default_rng(seed)
    n, period = 5, 0.001
    a_max = rng.uniform(5.0, 20.0, n)
    jerk = rng.uniform(2000.0, 10000.0, n)
    q_max = rng.uniform(0.05, 0.5, n)
    u1 = rng.uniform(0.0, 0.5, n)
    acc = np.minimum(a_max, rng.uniform(0.0, 1.0, n) * a_max)
    u2 = u1 - period * acc
    box = np.empty((4, n))
    big = np.full(n, 1e3)
    applied_jerk_box(np.zeros(n), u1, u2, a_max, jerk, big, -big, q_max, period, box)
    for k in range(n):
        v0 = min(box[1, k], box[3, k])  # the fastest admissible command
        b = min(a_max[k], 2.0 * jerk[k] * period)
        acc0 = (v0 - u1[k]) / period
        travelled = period * v0 + _stop_distance(v0, acc0, b, jerk[k], period)
        assert travelled <= q_max[k] + 1e-9


def test_terminal_coefficient_covers_a_jerk_limited_stop():
    """``q_p + (v̄/(2ā) + ā/(2j̄)) qd_{p-1}``: the continuous stop from rest acceleration
    (ramp to ``-ā`` at ``j̄``, hold, ramp back) covers at most that, by integration."""
    n, period = 2, 0.01
    breaks = interval_breakpoints(3, 0.3, period)
    model = ConsistentPrediction(breaks, n, period)
    qd_max, a, j = np.array([2.0, 1.0]), np.array([10.0, 4.0]), np.array([400.0, 1000.0])
    limit = PredictedPositionLimit(model.layout, -np.ones(n), np.ones(n), qd_max, jerk_max=j)
    model.commit(np.zeros((3, n)), np.zeros(3))
    pred = model.predict(np.zeros(n), 0.0)
    rows = {
        r.name: r for r in limit.rows(SimpleNamespace(prediction=pred, a_max=np.tile(a, (3, 1))))
    }
    last = model.layout.qd_index()[-1]
    coeff = rows["terminal_braking"].C[np.arange(n), last] - pred.weights[-1, -1]
    np.testing.assert_allclose(coeff, qd_max / (2 * a) + a / (2 * j))
    dt = 1e-5
    for k in range(n):
        for v0 in np.linspace(0.05, qd_max[k], 7):
            v, acc, dist, rising = v0, 0.0, 0.0, False
            while v > 0.0 and not (rising and acc == 0.0):
                # bang-bang jerk: down to -ā, back up once the speed left is what that takes
                rising = rising or v <= acc * acc / (2.0 * j[k])
                acc = min(acc + j[k] * dt, 0.0) if rising else max(acc - j[k] * dt, -a[k])
                v += acc * dt
                dist += max(v, 0.0) * dt
            assert v < 1e-3  # at rest, up to the integration's step
            assert dist <= coeff[k] * v0 + 1e-6


def _check_step(robot, u, u1, u2, q, v_max, a_max, jerk, period):
    assert np.all(np.abs(u) <= v_max * (1 + RTOL))
    assert np.all(np.abs(u - u1) <= a_max * period * (1 + RTOL) + 1e-12)
    assert np.all(np.abs(u - 2 * u1 + u2) <= jerk * period**2 * (1 + RTOL) + 1e-12)
    assert np.all(q >= robot.limits.q_min) and np.all(q <= robot.limits.q_max)


def _moving_state(robot, rng, a_max, jerk, period):
    """A state at speed (and, for some joints, at the acceleration bound) from which a
    jerk-limited stop fits: one joint near its position limit, moving towards it."""
    n = robot.nq
    lo, hi = robot.limits.q_min + 0.01, robot.limits.q_max - 0.01
    v = PANDA_V * rng.uniform(0.3, 1.0, n) * rng.choice([-1.0, 1.0], n)
    acc = a_max * rng.choice([-1.0, 0.0, 1.0], n)
    same = np.sign(acc) == np.sign(v)
    room = PANDA_V - acc**2 / (2 * jerk)  # accelerating outwards needs a²/(2j̄) of speed
    v = np.where(same, np.sign(v) * np.minimum(np.abs(v), room), v)
    b = np.minimum(a_max, 2 * jerk * period)
    need = (np.abs(v) + a_max**2 / jerk) ** 2 / (2 * b) + np.abs(v) * (
        4 * a_max / jerk + 2 * period
    )
    centre = np.clip(PANDA_Q0, lo + need, hi - need)
    q = centre.copy()
    k = int(rng.integers(n))  # this one starts near the limit it moves towards
    q[k] = (
        hi[k] - need[k] * rng.uniform(1.05, 1.3)
        if v[k] > 0
        else lo[k] + need[k] * rng.uniform(1.05, 1.3)
    )
    return np.clip(q, lo, hi), v, v - period * acc


def _closed_loop(controller, robot, q, u1, u2, steps, a_max, jerk, period):
    controller.reset(q, u1)
    controller.qd_before_prev = u2.copy()
    for _ in range(steps):
        r = controller.step(q)
        assert not r.diagnostics.fallback, r.diagnostics.message
        u = r.qd_command
        q = q + period * u
        _check_step(robot, u, u1, u2, q, PANDA_V, a_max, jerk, period)
        u1, u2 = u.copy(), u1


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_path_following_stays_within_every_limit_from_moving_states(panda, seed):
    """8 random moving states, 125 steps each: every command within every limit, every
    next problem solved (no fallback)."""
    rng = np.random.default_rng(seed)
    period = 0.001
    a_max = rng.uniform(5.0, 20.0, 7)
    jerk = rng.uniform(2000.0, 12000.0, 7)
    q, u1, u2 = _moving_state(panda, rng, a_max, jerk, period)
    ctrl = PathFollowingController(panda, Circle(1.0, 0.15), period, velocity_limits=PANDA_V,
                                   acceleration_limit=a_max, jerk_limit=jerk)  # fmt: skip
    _closed_loop(ctrl, panda, q, u1, u2, 125, a_max, jerk, period)


@pytest.mark.parametrize("seed", [23, 69])
def test_path_following_from_an_acceleration_bound_under_a_slow_jerk(panda, seed):
    """States drawn as above whose jerk bounds are slow against their acceleration bounds
    (the acceleration takes 2–2.7 ms to turn round): the plan's reserve between intervals
    is one the first jerk row can reach from an applied acceleration at its bound."""
    test_path_following_stays_within_every_limit_from_moving_states.hypothesis.inner_test(
        panda, seed
    )


def test_the_reserve_under_a_jerk_bound_is_reachable_within_the_first_jerk_row(panda):
    from dqcontrol.controllers.path_following.tuning import RESERVE_REPLANNED_OFTEN

    def limit(**kwargs):
        ctrl = PathFollowingController(panda, Circle(1.0, 0.15), 0.001, velocity_limits=PANDA_V,
                                       **kwargs)  # fmt: skip
        lim = next(lim for lim in ctrl.limits if lim.name == "acceleration")
        coupling = 0.5 * (ctrl.layout.durations_s[1:] + ctrl.layout.durations_s[:-1])
        return lim.coupling_s[0] / coupling[0], ctrl.layout.durations_s

    franka = limit(acceleration_limit=15.0, jerk_limit=7500.0)[0]
    assert franka == pytest.approx(RESERVE_REPLANNED_OFTEN, rel=1e-12)
    reserve, durations = limit(acceleration_limit=20.0, jerk_limit=2000.0)
    m_0 = 0.5 * (0.001 + 0.5 * (durations[0] + durations[1]))
    assert reserve == pytest.approx(1.0 - 2000.0 * m_0 / 20.0, rel=1e-12)
    assert reserve > RESERVE_REPLANNED_OFTEN


@pytest.mark.parametrize("cls", [LocalController, ProportionalController])
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_applied_command_controllers_stay_within_every_limit_from_moving_states(panda, cls, seed):
    """20 random moving states, 100 steps each (2000 steps), as above: the local controller
    (jerk rows on its applied command) and the proportional one (the jerk interval in its
    box)."""
    rng = np.random.default_rng(seed)
    period = 0.001
    a_max = rng.uniform(5.0, 20.0, 7)
    jerk = rng.uniform(2000.0, 12000.0, 7)
    q, u1, u2 = _moving_state(panda, rng, a_max, jerk, period)
    ctrl = cls(panda, Circle(1.0, 0.15), period, velocity_limits=PANDA_V,
               acceleration_limit=a_max, jerk_limit=jerk)  # fmt: skip
    _closed_loop(ctrl, panda, q, u1, u2, 100, a_max, jerk, period)


def _circle_commands(controller, steps_max=4000):
    q = PANDA_Q0.copy()
    controller.reset(q)
    commands = [np.zeros(7), np.zeros(7)]
    while not controller.done and len(commands) < steps_max:
        r = controller.step(q)
        assert not r.diagnostics.fallback
        commands.append(r.qd_command.copy())
        q = q + controller.period_s * r.qd_command
    return np.array(commands)


@pytest.mark.parametrize("cls", [PathFollowingController, LocalController, ProportionalController])
def test_panda_circle_at_one_millisecond_keeps_franka_jerk(panda, cls):
    """The Panda on a 15 cm circle of 1 s at T = 1 ms, Franka's limits: every second
    difference of the applied commands within ``j̄ T²``."""
    period = 0.001
    ctrl = cls(panda, Circle(1.0, 0.15), period, velocity_limits=PANDA_V,
               acceleration_limit=PANDA_A, jerk_limit=PANDA_J)  # fmt: skip
    u = _circle_commands(ctrl)
    assert ctrl.done
    jerk = np.abs(np.diff(u, 2, axis=0)) / period**2
    assert np.max(jerk / PANDA_J) <= 1 + RTOL
    assert np.max(np.abs(np.diff(u, axis=0)) / period / PANDA_A) <= 1 + RTOL


def test_no_jerk_rows_without_a_finite_jerk(panda):
    ctrl = PathFollowingController(panda, Circle(1.0, 0.15), 0.01)
    assert not any(isinstance(lim, JerkLimit) for lim in ctrl.limits)
    ctrl = PathFollowingController(panda, Circle(1.0, 0.15), 0.01, jerk_limit=5000.0)
    assert sum(isinstance(lim, JerkLimit) for lim in ctrl.limits) == 1
    franka = panda.with_limits("franka_panda")  # a profile with jerk limits
    ctrl = LocalController(franka, Circle(1.0, 0.15), 0.01)
    (limit,) = (lim for lim in ctrl.limits if isinstance(lim, JerkLimit))
    np.testing.assert_array_equal(limit.jerk, PANDA_J)


@pytest.mark.parametrize("bad", [-1.0, 0.0, np.inf, [1.0, 2.0]])
def test_bad_jerk_limit_is_refused(panda, bad):
    with pytest.raises(ParameterError, match="jerk_limit"):
        LocalController(panda, Circle(1.0, 0.15), 0.01, jerk_limit=bad)
