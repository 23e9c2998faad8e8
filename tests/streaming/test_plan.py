"""dqcontrol/streaming/plan.py: a plan's positions, velocities and phase against a fine
numeric integration of its piecewise-constant velocities (numpy), a fallback plan's rest
after its first interval, and the plan of a path-following step's horizon."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.base import StepDiagnostics, StepResult
from dqcontrol.streaming.plan import Plan, plan_from_result

DURATIONS = np.array([0.01, 0.03, 0.02, 0.04])


def _plan(seed: int, stop_after_first: bool = False) -> Plan:
    rng = np.random.default_rng(seed)
    return Plan(
        plan_id=3, start_k=10, made_s=0.009, q_start=rng.standard_normal(2), sigma_start=0.5,
        durations_s=DURATIONS, qd=rng.uniform(-1, 1, (4, 2)), s=rng.uniform(0, 1, 4),
        stop_after_first=stop_after_first,
    )  # fmt: skip


def _integrated(plan: Plan, tau_s: float, step_s: float = 1e-6):
    """Position and phase at ``tau_s`` by summing the interval velocities over a fine grid."""
    grid = (np.arange(round(tau_s / step_s)) + 0.5) * step_s
    index = np.searchsorted(np.cumsum(DURATIONS), grid, side="right")
    q = plan.q_start + step_s * plan.qd[index].sum(axis=0)
    return q, plan.sigma_start + step_s * plan.s[index].sum()


@pytest.mark.parametrize("tau_s", [0.0, 0.004, 0.01, 0.025, 0.0555, 0.0999])
def test_position_and_phase_are_the_integrated_plan(tau_s):
    plan = _plan(1)
    q, sigma = _integrated(plan, tau_s)
    np.testing.assert_allclose(plan.position(tau_s), q, atol=1e-9)
    assert plan.phase(tau_s) == pytest.approx(sigma, abs=1e-9)


def test_the_breakpoints_and_the_states_there():
    plan = _plan(2)
    np.testing.assert_allclose(plan.ends_s, [0.0, 0.01, 0.04, 0.06, 0.10])
    assert plan.duration_s == pytest.approx(0.1)
    states = plan.states()
    for i, tau in enumerate(plan.ends_s):
        np.testing.assert_allclose(states[i], _integrated(plan, tau)[0], atol=1e-9)
    states[0] = 99.0  # a copy: the plan keeps its own
    assert not (plan.q_at == 99.0).any()


def test_velocity_is_that_of_the_interval_and_zero_outside():
    plan = _plan(3)
    for tau, i in ((0.0, 0), (0.0099, 0), (0.01, 1), (0.05, 2), (0.0999, 3)):
        np.testing.assert_array_equal(plan.velocity(tau), plan.qd[i])
    assert not plan.velocity(0.1).any() and not plan.velocity(-0.001).any()
    np.testing.assert_allclose(plan.position(0.5), plan.states()[-1])  # held past the end
    assert plan.phase(0.5) == pytest.approx(plan.sigma_at[-1])


def test_the_mean_velocity_reaches_the_position_exactly():
    plan = _plan(4)
    for tau0, tau1 in ((0.0, 0.02), (0.005, 0.035), (0.09, 0.2)):
        u = plan.mean_velocity(tau0, tau1)
        np.testing.assert_allclose(
            plan.position(tau0) + (tau1 - tau0) * u, plan.position(tau1), atol=1e-15
        )
    np.testing.assert_array_equal(plan.mean_velocity(0.02, 0.02), plan.velocity(0.02))


def test_a_fallback_plan_rests_after_its_first_interval():
    plan = _plan(5, stop_after_first=True)
    first_end = plan.q_start + 0.01 * plan.qd[0]
    np.testing.assert_array_equal(plan.velocity(0.005), plan.qd[0])
    assert not plan.velocity(0.02).any()
    np.testing.assert_allclose(plan.position(0.05), first_end, atol=1e-15)
    assert plan.phase(0.05) == pytest.approx(0.5 + 0.01 * plan.s[0])


def test_the_plan_of_a_step_starts_with_its_applied_command():
    rng = np.random.default_rng(6)
    horizon = rng.standard_normal((4, 2))
    result = StepResult(
        qd_command=np.array([0.3, -0.2]), s=0.7, sigma=1.25, sigma_next=1.26,
        pose=np.zeros(8), target=np.zeros(8), diagnostics=StepDiagnostics("solved"),
        horizon_qd=horizon, horizon_s=np.full(4, 0.9),
    )  # fmt: skip
    plan = plan_from_result(result, DURATIONS, plan_id=2, start_k=5, made_s=0.004, q_start=[1, 2])
    np.testing.assert_array_equal(plan.qd[0], [0.3, -0.2])
    np.testing.assert_array_equal(plan.qd[1:], horizon[1:])
    np.testing.assert_array_equal(plan.s, [0.7, 0.9, 0.9, 0.9])
    assert plan.sigma_start == 1.25 and plan.q_start.tolist() == [1.0, 2.0]
    assert (plan.plan_id, plan.start_k, plan.made_s) == (2, 5, 0.004)
    assert not plan.stop_after_first
    assert horizon[0].tolist() != [0.3, -0.2]  # the step's horizon is left as it was
