"""Hard bounds under faults: property tests of the bounds and the fallback, the
fault-injection wrappers, a reduced fault campaign, and ``dqcontrol faults``.

``tests/controllers/test_controllers.py`` already checks three steps of the QP controllers
from random states against :func:`command_box`; here the properties are over random *parameters* too
(periods, limits, trajectories, σ0), over whole admissible command sequences, for the
fallback and for the proportional controller, and under corrupted measurements.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dqcontrol.cli import main
from dqcontrol.controllers import (
    LocalController,
    PathFollowingController,
    PredictiveController,
    PredictiveNoScalingController,
    ProportionalController,
    command_box,
    safe_command,
)
from dqcontrol.errors import ParameterError
from dqcontrol.faults import (
    ContradictoryBoundsQP,
    contradictory,
    fault_driver,
    render_csv,
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
from dqcontrol.model import LBR4P_Q0
from dqcontrol.registry import controller_spec
from dqcontrol.sim import (
    FaultyDriver,
    KinematicDriver,
    MujocoDriver,
    NotASimulatorError,
    PayloadDriver,
    TorqueLimitDriver,
    run_loop,
    run_mujoco,
)
from dqcontrol.trajectories import Circle, Sinusoid

TOL = 1e-9


# =========================================================================== bounds.py
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
@pytest.mark.parametrize("delay", [0, 1, 2, 3])
def test_delay_returns_the_measurement_of_d_periods_ago(lbr4p, delay):
    drv = FaultyDriver(KinematicDriver(lbr4p, 0.05), delay_periods=delay)
    seen = [drv.reset(LBR4P_Q0).q]
    for k in range(6):
        drv.write(np.full(7, 0.1 * (k + 1)))
        seen.append(drv.read().q)
    true = drv.true_q
    for k, q in enumerate(seen):
        np.testing.assert_array_equal(q, true[max(0, k - delay)])
    assert drv.read().t_s == pytest.approx(6 * 0.05)  # the clock itself is not delayed


def test_noise_is_seeded_gaussian_and_restarts_at_reset(lbr4p):
    drv = FaultyDriver(KinematicDriver(lbr4p, 0.05), q_noise_rad=2e-3, qd_noise_rad_s=0.02, seed=7)

    def run() -> list[np.ndarray]:
        seen = [drv.reset(LBR4P_Q0).q]
        for _ in range(400):
            drv.hold()
            seen.append(drv.read().q)
        return seen

    first, again = run(), run()
    np.testing.assert_array_equal(first, again)
    err = np.array(first) - LBR4P_Q0
    assert abs(err.mean()) < 2e-4 and err.std() == pytest.approx(2e-3, rel=0.05)
    np.testing.assert_array_equal(drv.true_q[-1], LBR4P_Q0)  # the arm itself did not move


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"q_noise_rad": -1e-3}, "q_noise_rad must be finite and ≥ 0 [rad]"),
        ({"qd_noise_rad_s": math.nan}, "qd_noise_rad_s must be finite and ≥ 0 [rad/s]"),
        ({"delay_periods": -1}, "delay_periods must be an integer ≥ 0"),
        ({"delay_periods": 1.5}, "delay_periods must be an integer ≥ 0"),
        ({"seed": "x"}, "seed must be an integer"),
    ],
)
def test_bad_fault_parameters(lbr4p, kwargs, fragment):
    with pytest.raises(ParameterError) as info:
        FaultyDriver(KinematicDriver(lbr4p, 0.05), **kwargs)
    assert fragment in str(info.value)


def test_a_case_driver_wraps_the_arm_in_its_faults(lbr4p):
    fault = fault_by_name("payload_3kg_torque_half")
    drv = fault_driver(fault, "mujoco", lbr4p, 0.05, seed=4)
    assert isinstance(drv, FaultyDriver) and drv.faults.seed == 4
    assert isinstance(drv.inner, TorqueLimitDriver)
    assert isinstance(drv.inner.inner, PayloadDriver)
    assert isinstance(drv.inner.inner.inner, MujocoDriver)
    assert drv.simulation.payload_kg == 3.0 and drv.simulation.effort_scale == 0.5
    assert drv.meta["payload_kg"] == 3.0 and drv.meta["effort_scale"] == 0.5
    plain = fault_driver(fault_by_name("noise"), "kinematic", lbr4p, 0.05)
    assert isinstance(plain.inner, KinematicDriver) and plain.faults.q_noise_rad == 2e-3
    with pytest.raises(NotASimulatorError, match="KinematicDriver cannot"):
        fault_driver(fault, "kinematic", lbr4p, 0.05)
    with pytest.raises(ParameterError, match="simulator must be one of"):
        fault_driver(fault, "gazebo", lbr4p, 0.05)


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


def test_contradictory_bounds_reach_the_solver(lbr4p):
    ctrl = contradictory(PredictiveController)(
        lbr4p, Circle(2.0), 0.05, num_instants=6, contradiction="coupled", window_steps=(1, 3)
    )
    assert isinstance(ctrl.qp, ContradictoryBoundsQP)
    assert type(ctrl).__name__ == "ContradictoryPredictiveController"
    ctrl.reset(LBR4P_Q0)
    q = LBR4P_Q0.copy()
    relaxed = []
    for _ in range(5):
        res = ctrl.step(q)
        relaxed.append(res.diagnostics.relaxed)
        q = q + 0.05 * res.qd_command
    # the controller's own remedy (dropping the predicted boxes) restores feasibility
    assert relaxed == [False, True, True, False, False]
    assert ctrl.qp.corrupted_solves == 2 and ctrl.qp.false_successes == 0
    lo, up, made = ctrl.qp.corrupt(*ctrl.last_problem()[3:])
    assert made and np.any(lo > ctrl.last_problem().lower)


def _corrupted(ctrl, steps: int, period_s: float) -> tuple[int, int, np.ndarray]:
    """``(corrupted solves, fallbacks, |qd| largest over the run)`` of a closed loop."""
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    fallbacks, qd_peak = 0, np.zeros(ctrl.n)
    for _ in range(steps):
        res = ctrl.step(q)
        fallbacks += res.diagnostics.fallback
        qd_peak = np.maximum(qd_peak, np.abs(res.qd_command))
        q = q + period_s * res.qd_command
    return ctrl.backend.corrupted_solves, fallbacks, qd_peak


@pytest.mark.parametrize("mode", ["crossed", "coupled"])
def test_contradictory_reaches_every_priority_mode(lbr4p, mode):
    """The wrapper sits on the one backend every QP of a step goes to: the strict
    priority's levels (the warm levels, the reduced levels) see it as the weighted
    controller's single level does."""
    counts = {}
    for priority in ("weighted", "strict"):
        ctrl = contradictory(PredictiveController)(
            lbr4p, Circle(2.0), 0.05, num_instants=6, contradiction=mode,
            window_steps=(2, 7), priority=priority,
        )  # fmt: skip
        counts[priority] = _corrupted(ctrl, 10, 0.05)[:2]
    assert counts["strict"] == counts["weighted"]
    assert counts["weighted"][0] >= 5  # every step of the window, and its relaxed retry


@pytest.mark.parametrize("mode", ["crossed", "coupled"])
def test_path_following_runs_the_contradictory_faults(lbr4p, mode):
    """No feasible point in the window: the path-following controller tries its remedies,
    then brakes within its bounds (the safe fallback), and resumes after the window."""
    ctrl = contradictory(PathFollowingController)(
        lbr4p, Circle(2.0), 0.05, contradiction=mode, window_steps=(2, 5),
        velocity_limits=1.0, acceleration_limit=5.0,
    )  # fmt: skip
    assert isinstance(ctrl.backend, ContradictoryBoundsQP) and ctrl.qp is ctrl.backend
    corrupted, fallbacks, qd_peak = _corrupted(ctrl, 12, 0.05)
    assert corrupted >= 3 and fallbacks == 3
    assert ctrl.backend.false_successes == 0
    assert np.all(qd_peak <= 1.0 + 1e-9)
    assert ctrl.sigma > 0.0  # the task went on after the window


def test_contradictory_needs_a_qp_controller(lbr4p):
    with pytest.raises(ParameterError, match="QP controller class"):
        contradictory(ProportionalController)
    with pytest.raises(ParameterError, match="mode 'coupled' needs a predictive controller"):
        contradictory(LocalController)(lbr4p, Circle(1.0), 0.05, contradiction="coupled")


# =========================================================================== the campaign
@pytest.fixture(scope="module")
def quick_campaign():
    """The reduced campaign of CI: kinematic loop, 4 controllers, the circle, 11 faults."""
    return run_campaign(simulator="kinematic", quick=True)


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


def test_report_and_csv(quick_campaign):
    md = render_markdown(quick_campaign, command="dqcontrol faults --quick")
    for heading in ("## Checks (QP controllers)", "## QP controllers", "## Proportional",
                    "## Graceful degradation: unreachable path", "## Faults"):  # fmt: skip
        assert heading in md
    for check in ("no exception from inside the loop", "no NaN", "no true joint-position",
                  "no commanded velocity/acceleration violation", "σ never decreases"):  # fmt: skip
        assert f"PASS — {check}" in md
    rows = list(csv.DictReader(io.StringIO(render_csv(quick_campaign))))
    assert len(rows) == len(quick_campaign.rows)
    assert {"fault", "controller", "status", "q_violations_true", "nan_seen"} <= set(rows[0])


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


def test_the_loop_sees_the_faulty_measurements_of_a_mujoco_arm(lbr4p):
    drv = FaultyDriver(MujocoDriver(lbr4p, 0.05), q_noise_rad=1e-3, delay_periods=1)
    ctrl = LocalController(lbr4p, Circle(1.0), 0.05)
    res = run_loop(ctrl, drv, q0=LBR4P_Q0, max_time_s=0.5, brake=False)
    assert len(res.log) == 10 and drv.true_q.shape == (11, 7)
    # the log holds what the controller measured: one period late and noisy
    assert np.abs(res.log.q[1:] - drv.true_q[:-2]).max() < 6e-3  # [k] is true [k - 1]
    assert np.abs(res.log.q[1:] - drv.true_q[:-2]).max() > 0.0


# =========================================================================== the command
def test_cli_writes_the_report_atomically(tmp_path, capsys):
    code = main(
        ["faults", "--quick", "--simulator", "kinematic", "--controllers", "local,proportional",
         "--faults", "nominal,solver_fails", "--out", str(tmp_path), "--no-progress"]
    )  # fmt: skip
    assert code == 0
    md = (tmp_path / "faults.md").read_text(encoding="utf-8")
    assert "solver_fails" in md and "simulator **kinematic**" in md
    assert len(list(csv.DictReader(open(tmp_path / "faults.csv", encoding="utf-8")))) == 3
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp files
    out = capsys.readouterr().out
    assert "wrote" in out and "2/2 cases without violation" in out


def test_cli_help_and_bad_options(capsys):
    with pytest.raises(SystemExit) as info:
        main(["faults", "--help"])
    assert info.value.code == 0
    assert "--simulator" in capsys.readouterr().out
    with pytest.raises(SystemExit) as info:
        main(["faults", "--workers", "0"])
    assert info.value.code == 2
    assert main(["faults", "--controllers", "pid", "--out", "/nonexistent"]) == 1


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
