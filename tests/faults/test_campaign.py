"""``dqcontrol.faults.campaign``: single cases in both simulators and a reduced campaign, judged on
the hard bounds; also (to move to their modules' tests) every controller's command within its
bounds under random parameters and noisy states."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
    ProportionalController,
    command_box,
)
from dqcontrol.errors import ParameterError
from dqcontrol.faults import (
    render_markdown,
    run_campaign,
    run_case,
)
from dqcontrol.faults.campaign import CaseSpec
from dqcontrol.faults.scenarios import (
    CONTROLLERS,
    TRAJECTORIES,
    ControllerSpec,
    Fault,
    fault_by_name,
)
from dqcontrol.registry import controller_spec
from dqcontrol.sim import (
    run_mujoco,
)
from dqcontrol.trajectories import Circle, Sinusoid

TOL = 1e-9


# =========================================================================== controllers
CONTROLLER_KINDS = ["local", "p6", "p10", "noscale", "proportional"]


def _make(kind, robot, traj, period, **kw):
    if kind == "local":
        return LocalController(robot, traj, period, **kw)
    if kind == "p6":
        return PredictiveController(robot, traj, period, num_instants=6, **kw)
    if kind == "p10":
        return PredictiveController(robot, traj, period, num_instants=10, **kw)
    if kind == "noscale":
        return PredictiveNoScalingController(robot, traj, period, num_instants=6, **kw)
    return ProportionalController(robot, traj, period, **kw)


@settings(max_examples=40)
@given(
    kind=st.sampled_from(CONTROLLER_KINDS),
    period=st.sampled_from([0.002, 0.01, 0.05, 0.1]),
    vel_scale=st.floats(0.2, 1.0),
    a_max=st.floats(1.0, 40.0),
    traj=st.sampled_from(["circle", "sinusoid"]),
    duration=st.floats(0.5, 8.0),
    sigma0_frac=st.floats(0.0, 0.9),
    noise=st.floats(0.0, 5e-3),
    seed=st.integers(0, 2**31 - 1),
)
def test_no_command_crosses_a_bound_under_random_parameters_and_noisy_states(
    lbr4p, kind, period, vel_scale, a_max, traj, duration, sigma0_frac, noise, seed
):
    """Random controller parameters, task and phase; the controller is fed noisy,
    partly out-of-limit measurements: every command is in the box of *what it measured*."""
    rng = np.random.default_rng(seed)
    lim = lbr4p.limits
    qd_max = vel_scale * lim.qd_max
    task = (Circle if traj == "circle" else Sinusoid)(duration)
    ctrl = _make(kind, lbr4p, task, period, velocity_limits=qd_max, acceleration_limit=a_max)
    q = rng.uniform(lim.q_min + 0.02, lim.q_max - 0.02)
    ctrl.reset(q, sigma0=sigma0_frac * duration)
    for _ in range(4):
        q_meas = q + rng.normal(0.0, noise, q.shape) if noise else q
        prev = ctrl.qd_prev.copy()
        res = ctrl.step(q_meas)
        qd = res.qd_command
        box = command_box(q_meas, prev, lim.q_min, lim.q_max, qd_max, np.full(7, a_max), period)
        assert np.all(np.isfinite(qd)) and 0.0 <= res.s <= 1.0
        assert box.contains(qd, TOL), (box.lower - qd, qd - box.upper)
        assert np.all(np.abs(qd - prev) <= period * a_max + TOL)
        assert res.sigma_next >= res.sigma
        q = q + period * qd


# =========================================================================== wrappers


def test_a_model_fault_case_equals_the_simulation_built_with_it(lbr4p):
    """The campaign's wrappers give the arm the simulator would have been built with."""
    spec = CaseSpec(
        CONTROLLERS["local"], TRAJECTORIES["circle"], fault_by_name("payload_3kg_torque_half"),
        "mujoco", 1.0,
    )  # fmt: skip
    row = run_case(spec, keep_log=True)
    ctrl = CONTROLLERS["local"].build(lbr4p, TRAJECTORIES["circle"].build(1.0), 0.05)
    ref = run_mujoco(
        ctrl, spec.fault.start_configuration(lbr4p), max_time_s=spec.max_time_s,
        payload_kg=3.0, payload_offset_m=np.array([0.0, 0.0, 0.05]), effort_scale=0.5,
    )  # fmt: skip
    assert len(row.log) == len(ref.log) > 10
    for name in ("q", "qd_measured", "qd_command", "torque", "torque_peak", "sigma"):
        np.testing.assert_array_equal(getattr(row.log, name), getattr(ref.log, name))
    nominal = run_case(replace(spec, fault=fault_by_name("nominal")), keep_log=True)
    assert not np.array_equal(nominal.log.torque, row.log.torque)  # the fault is felt


# =========================================================================== the campaign


def _row(result, fault, controller):
    (row,) = [r for r in result.rows if r.fault == fault and r.controller == controller]
    return row


def test_quick_campaign_qp_controllers_hold_every_bound(quick_campaign):
    qp = quick_campaign.qp_rows
    assert len(qp) >= 30 and not quick_campaign.interrupted
    for r in qp:
        where = f"{r.fault}/{r.trajectory}/{r.controller}"
        assert not r.raised, where  # the loop never raises from inside a step
        assert not r.nan_seen, where
        assert (r.velocity_violations, r.acceleration_violations) == (0, 0), where
        assert r.q_violations_true == 0 and r.q_violations_measured == 0, where
        assert r.sigma_monotone and r.s_in_range, where  # σ never decreases
        # graceful degradation: never moving without the task advancing
        assert r.status in ("completed", "stopped", "advancing"), where
        if r.status == "completed":
            assert r.sigma_reached_s == pytest.approx(r.duration_s)


def test_quick_campaign_proportional_clips_to_the_bounds(quick_campaign):
    for r in quick_campaign.proportional_rows:
        assert not r.raised and not r.nan_seen
        assert (r.velocity_violations, r.acceleration_violations) == (0, 0)


def test_unreachable_path_stalls_near_the_path_instead_of_deforming_it(quick_campaign):
    """s → 0 and the tool stays within a few mm of the path, where the controllers without
    time scaling leave it by tens of centimetres."""
    for name in ("local", "predictive_p6"):
        r = _row(quick_campaign, "unreachable", name)
        assert not r.completed and r.sigma_reached_s < 0.3 * r.duration_s
        assert r.s_end < 0.02
        assert r.status == "stopped" and r.speed_end_rad_s < 0.05  # at rest, on the path
        assert r.path_dev_max_m < 0.02 and r.path_dev_end_m < 0.02
    assert _row(quick_campaign, "unreachable", "proportional").path_dev_max_m > 0.2
    assert _row(quick_campaign, "unreachable", "predictive_noscale_p6").path_dev_max_m > 0.2


def test_failing_or_timed_out_solver_stops_the_arm_safely(quick_campaign):
    for fault in ("solver_fails", "solver_timeout"):
        for name in ("local", "predictive_p6", "predictive_noscale_p6"):
            r = _row(quick_campaign, fault, name)
            assert r.status == "stopped" and r.sigma_reached_s == 0.0
            assert r.fallbacks > 0 and r.speed_end_rad_s == 0.0


def test_coupled_contradiction_is_relaxed_and_the_task_completes(quick_campaign):
    for name in ("predictive_p6", "predictive_noscale_p6"):
        r = _row(quick_campaign, "qp_coupled", name)
        assert r.completed and r.relaxed_steps == 20 and r.fallbacks == 0


def test_crossed_bounds_are_never_reported_solved(quick_campaign):
    for name in ("local", "predictive_p6", "predictive_noscale_p6"):
        r = _row(quick_campaign, "qp_crossed", name)
        assert r.false_successes == 0 and r.fallbacks >= 20


def test_campaign_interrupted_keeps_the_completed_rows():
    calls = []

    def stop_after_two(row, done, total):
        calls.append(row)
        if done == 2:
            raise KeyboardInterrupt

    res = run_campaign(
        ["local"], ["circle"], ["nominal", "solver_fails", "far_start"], "kinematic",
        workers=1, on_result=stop_after_two,
    )  # fmt: skip
    assert res.interrupted and len(res.rows) == 2 and res.total_cases == 3
    assert "interrupted after 2 of 3 cases" in res.note
    assert "Incomplete" in render_markdown(res)


def test_unknown_names_are_refused():
    with pytest.raises(ParameterError, match="unknown controllers"):
        run_campaign(["pid"], simulator="kinematic")
    with pytest.raises(ParameterError, match="unknown fault 'gremlins'"):
        run_campaign(faults=["gremlins"], simulator="kinematic")
    with pytest.raises(ParameterError, match="simulator must be one of"):
        run_campaign(simulator="gazebo")


# =========================================================================== MuJoCo
@pytest.mark.parametrize(
    ("fault", "traj", "controller"),
    [
        ("noise_delay_2", "circle", "predictive_p6"),
        ("payload_3kg_torque_half", "sinusoid", "local"),
        ("qp_crossed", "circle", "local"),
    ],
)
def test_short_mujoco_cases_hold_every_bound(fault, traj, controller):
    spec = CaseSpec(
        CONTROLLERS[controller], TRAJECTORIES[traj], fault_by_name(fault), "mujoco",
        TRAJECTORIES[traj].quick_duration_s,
    )  # fmt: skip
    r = run_case(spec)
    assert r.safe, r.row()
    assert r.completed and not r.nan_seen and r.q_violations_true == 0


def test_mujoco_near_the_limits_stays_within_them():
    spec = CaseSpec(
        CONTROLLERS["local"], TRAJECTORIES["circle"], fault_by_name("near_limits"), "mujoco",
        2.0,
    )  # fmt: skip
    assert run_case(spec).q_violations_true == 0


@pytest.mark.parametrize("delay", [1, 2])
def test_delay_near_the_limits_overshoots_by_at_most_d_periods_of_motion(lbr4p, delay):
    """A controller fed d-period-old positions bounds its command from a stale q: in the
    ideal loop the joints may pass a limit by up to d·T·qd_max (finding; the fix — predict
    q from the commands sent since — is ``measurement_delay_periods``, tested below)."""
    fault = Fault("x", "task", "", start="near_limits", delay_periods=delay, compensated=False)
    r = run_case(CaseSpec(CONTROLLERS["local"], TRAJECTORIES["circle"], fault, "kinematic", 2.0))
    assert r.velocity_violations == r.acceleration_violations == 0 and not r.nan_seen
    assert 0.0 < r.q_excess_true_rad <= delay * 0.05 * lbr4p.limits.qd_max.max() + 1e-9


# =========================================================================== delays and QP faults
@pytest.mark.parametrize("delay", [1, 2])
def test_delay_compensation_keeps_the_joints_within_their_limits(delay):
    """With ``measurement_delay_periods = d`` the controller works from q + T Σ(last d
    commands): in the ideal loop that is the true q, so the limits hold exactly again."""
    fault = Fault("x", "task", "", start="near_limits", delay_periods=delay, compensated=False)
    local = ControllerSpec(
        "local_compensated", LocalController, (("measurement_delay_periods", delay),)
    )
    r = run_case(CaseSpec(local, TRAJECTORIES["circle"], fault, "kinematic", 2.0))
    assert r.q_violations_true == 0 and r.safe, r.row()
    # the campaign's own delay faults configure the controller the same way
    r = run_case(
        CaseSpec(CONTROLLERS["local"], TRAJECTORIES["circle"],
                 Fault("y", "task", "", start="near_limits", delay_periods=delay),
                 "kinematic", 2.0)
    )  # fmt: skip
    assert r.q_violations_true == 0 and r.safe, r.row()


@pytest.mark.parametrize(
    "fault", ["qp_crossed", "qp_coupled", "solver_fails", "solver_timeout", "solver_flaky"]
)
def test_path_following_runs_every_qp_fault_safely(fault):
    """The campaign's QP faults reach the path-following controller through its backend:
    contradictory bounds are refused (the safe fallback over the whole window, then the
    task completes), a failing solver never moves the arm past a bound."""
    spec = CaseSpec(
        controller_spec("pf").renamed("path_following"), TRAJECTORIES["circle"],
        fault_by_name(fault), "kinematic", TRAJECTORIES["circle"].quick_duration_s,
    )  # fmt: skip
    r = run_case(spec)
    assert r.raised == "" and not r.nan_seen, r.row()
    assert r.velocity_violations == r.acceleration_violations == r.q_violations_true == 0
    assert r.false_successes == 0
    if fault.startswith("qp_"):
        assert r.completed and r.fallbacks == 20, r.row()


# =========================================================================== path following
PF = "path_following"


def _case(fault: str, traj: str, simulator: str) -> CaseSpec:
    """The campaign's case (the controller from the registry, as the campaign takes it)."""
    return CaseSpec(
        controller_spec("pf").renamed(PF), TRAJECTORIES[traj], fault_by_name(fault), simulator,
        TRAJECTORIES[traj].duration_s,
    )  # fmt: skip


def _judged(r) -> None:
    """The campaign's judgement of a QP controller's row."""
    assert r.safe and r.raised == "" and not r.nan_seen, r.row()
    assert r.status in ("completed", "stopped", "advancing"), r.row()


def test_noise_near_the_limits_stops_still():
    """A task stalled near the limits under measurement noise stands still (the noise-free
    case stops there too) instead of chasing the noise."""
    r = run_case(_case("near_limits_noise", "circle", "kinematic"))
    _judged(r)
    assert r.status in ("stopped", "completed"), r.row()


class _FirstTwoSeconds(CaseSpec):
    """A case cut at 2 s (the joint reaches its limit at 1.75 s)."""

    max_time_s = 2.0


def test_delay_near_the_limits_keeps_the_true_joints_inside_in_mujoco():
    """Near the limits with a 2-period delay (compensated) the servo's lag must not carry
    a joint past its limit: the sinusoid's first swing brings joint 6 to its lower limit at
    1.36 rad/s. The campaign tells the controller the MuJoCo servo it drives (τ_v), whose
    lag its prediction then counts."""
    base = _case("near_limits_delay_2", "sinusoid", "mujoco")
    spec = _FirstTwoSeconds(base.controller, base.trajectory, base.fault, "mujoco", 4.0)
    r = run_case(spec)
    assert r.raised == "" and not r.nan_seen, r.row()
    assert r.q_violations_true == 0, r.row()
