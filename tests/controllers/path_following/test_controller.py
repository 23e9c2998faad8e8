"""The path-following predictive controller: prediction, linearisation, levels, limits,
behaviour (docs/theory.md §8)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dqcontrol.controllers.backends import DaqpBackend
from dqcontrol.controllers.core.levels import held_rows, level_qp, solve_levels
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.controllers.prediction.consistent import interval_breakpoints, shift_matrix
from dqcontrol.controllers.terms.path_error import tangent_projectors
from dqcontrol.dq.algebra import translation
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0, PANDA_Q0
from dqcontrol.sim.kinematic import run_kinematic
from dqcontrol.trajectories import Circle, Sinusoid, WaypointTrajectory

THESIS_QD_MAX = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
T = 0.05


def _controller(robot, trajectory, **kwargs) -> PathFollowingController:
    kwargs.setdefault("velocity_limits", THESIS_QD_MAX)
    kwargs.setdefault("acceleration_limit", 10.0)
    return PathFollowingController(robot, trajectory, T, **kwargs)


def _advance(robot, controller, q, steps: int):
    """Run ``steps`` ideal kinematic steps; the last result and the state."""
    result = None
    for _ in range(steps):
        result = controller.step(q)
        q = q + controller.period_s * result.qd_command
    return result, q


def _decision(result) -> np.ndarray:
    return np.column_stack([result.horizon_qd, result.horizon_s]).ravel()


# ----------------------------------------------------------------------------- prediction
def test_breakpoints_first_interval_is_the_period_and_grow():
    b = interval_breakpoints(10, 1.0, 0.05)
    assert b[0] == 0.0 and b[1] == pytest.approx(0.05) and b[-1] == pytest.approx(1.0)
    assert np.all(np.diff(np.diff(b[1:])) > 0.0)


def test_breakpoints_grow_as_the_given_power():
    k = np.arange(1, 11, dtype=float)
    for growth in (2.0, 3.0, 1.0):
        b = interval_breakpoints(10, 1.0, 0.001, growth)
        expected = 0.001 + 0.999 * ((k - 1.0) / 9.0) ** growth  # b_1 … b_10
        np.testing.assert_allclose(b[1:], expected, rtol=1e-15)
    default = interval_breakpoints(10, 1.0, 0.001)
    np.testing.assert_array_equal(default, interval_breakpoints(10, 1.0, 0.001, 2.0))
    with pytest.raises(ParameterError, match="growth"):
        interval_breakpoints(10, 1.0, 0.001, 0.5)


def test_under_a_jerk_bound_the_second_interval_is_the_accelerations_turn(panda):
    """Without a jerk bound the intervals grow parabolically (the second is 12.3 ms at 1 kHz
    over 1 s); with one, as fast as lets the second last no longer than the shortest time a
    joint's acceleration takes to turn from one bound to the other, ``2 ā/j̄`` (4 ms with
    Franka's limits); a given growth is kept either way."""
    from dqcontrol.controllers.path_following.tuning import PathFollowingTuning

    def durations(robot, **kwargs):
        ctrl = PathFollowingController(robot, Circle(1.0), 0.001, **kwargs)
        return ctrl.layout.durations_s

    profiled = panda.with_limits("franka_panda")
    parabolic = np.diff(interval_breakpoints(10, 1.0, 1e-3))
    np.testing.assert_allclose(durations(panda), parabolic)
    assert durations(profiled)[1] == pytest.approx(2.0 * 7.5 / 3750.0, rel=1e-12)
    assert np.all(np.diff(durations(profiled)) > 0.0) and durations(profiled).sum() == 1.0
    turn = 2.0 * 10.0 / 5000.0  # a constant 10 rad/s² against 5000 rad/s³
    constant = durations(panda, jerk_limit=5000.0, acceleration_limit=10.0)
    assert constant[1] == pytest.approx(turn, rel=1e-12)
    # a jerk bound loose enough to turn within the parabolic second interval changes nothing
    np.testing.assert_allclose(durations(panda, jerk_limit=1e3, acceleration_limit=10.0), parabolic)
    given = PathFollowingTuning(interval_growth=2.0)
    np.testing.assert_array_equal(durations(profiled, tuning=given), durations(panda))


def test_shift_matrix_rows_are_averages():
    b = interval_breakpoints(6, 1.0, 0.05)
    s = shift_matrix(b, 0.05)
    np.testing.assert_allclose(s.sum(axis=1), 1.0)
    v = np.arange(6.0)
    # the mean of the shifted piecewise-constant profile, computed by fine sampling
    fine = np.linspace(0.0, 2.0, 400001)
    idx = np.minimum(np.searchsorted(b, fine, side="right") - 1, 5)
    for i in range(6):
        mask = (fine >= b[i] + 0.05) & (fine < b[i + 1] + 0.05)
        assert (s @ v)[i] == pytest.approx(v[idx[mask]].mean(), abs=1e-3)


def test_predicted_states_equal_the_integrated_decision(lbr4p):
    c = _controller(lbr4p, Circle(2.0))
    c.reset(LBR4P_Q0)
    result, q = _advance(lbr4p, c, LBR4P_Q0.copy(), 5)
    qd, s = result.horizon_qd, result.horizon_s
    durations = c.layout.durations_s
    weights = c.prediction_model.weights
    q_pred = q - T * result.qd_command + weights @ qd  # the states from this step's q
    expected = q - T * result.qd_command + np.cumsum(durations[:, None] * qd, axis=0)
    np.testing.assert_allclose(q_pred, expected, rtol=0, atol=1e-14)
    sig = result.sigma + weights @ s
    np.testing.assert_allclose(sig, result.sigma + np.cumsum(durations * s), atol=1e-14)


def test_linearised_path_error_matches_finite_differences(lbr4p):
    c = _controller(lbr4p, Sinusoid(4.0))
    c.reset(LBR4P_Q0)
    q0 = LBR4P_Q0.copy()
    _, q = _advance(lbr4p, c, q0, 8)
    sigma = c.sigma
    c.step(q)
    problem = c.last_problem()
    path = problem.levels[0].residuals[0]
    pred = c.prediction_model.predict(q, sigma)  # the shifted plan: a decision z_bar
    z_bar = np.column_stack([pred.warm_qd, pred.warm_s]).ravel()
    rng = np.random.default_rng(3)
    direction = rng.normal(size=z_bar.size)

    def true_error(z):
        qd, s = c.layout.split(z)
        qs = q + c.prediction_model.weights @ qd
        sig = sigma + c.prediction_model.weights @ s
        xs = lbr4p.poses(qs)
        xd, _ = c.trajectory.targets(sig)
        xs = np.where((np.einsum("pk,pk->p", xs, xd) < 0)[:, None], -xs, xs)
        return np.einsum("pab,pb->pa", tangent_projectors(problem_poses), xs - xd).ravel()

    problem_poses = lbr4p.poses(pred.q_lin)
    xd_lin, _ = c.trajectory.targets(pred.sigma_lin)
    flip = np.einsum("pk,pk->p", problem_poses, xd_lin) < 0
    problem_poses = np.where(flip[:, None], -problem_poses, problem_poses)
    # rebuild the linearisation at z_bar itself (the step above used the same point)
    c2 = _controller(lbr4p, Sinusoid(4.0))
    c2.reset(LBR4P_Q0)
    _advance(lbr4p, c2, q0, 8)
    ctx = c2._context_at(q, c2.prediction_model.at(q, sigma, pred.warm_qd, pred.warm_s))
    lin = PathErrorLinear(ctx)
    lin_a = lin.dense(ctx.layout)
    h = 1e-6
    fd = (true_error(z_bar + h * direction) - true_error(z_bar - h * direction)) / (2 * h)
    np.testing.assert_allclose(lin_a @ direction, fd, rtol=0, atol=5e-8)
    np.testing.assert_allclose(lin_a @ z_bar - lin.b, true_error(z_bar), rtol=0, atol=1e-12)
    assert path.dense(problem.layout).shape == lin_a.shape


def PathErrorLinear(ctx):  # noqa: N802 - reads like the term it evaluates
    from dqcontrol.controllers.terms.path_error import PathErrorTerm

    return PathErrorTerm().residual(ctx)


# ----------------------------------------------------------------------------- levels
def _level_optimum(qp) -> float:
    """The optimal value of a dense QP by quadprog (an independent active-set solver)."""
    import quadprog

    nv = qp.c.size
    a, lo, up = qp.A, qp.lower, qp.upper
    fin_lo, fin_up = np.isfinite(lo), np.isfinite(up)
    c_mat = np.vstack([a[fin_lo], -a[fin_up]]).T
    b_vec = np.concatenate([lo[fin_lo], -up[fin_up]])
    p = qp.P + 1e-12 * np.eye(nv)
    x = quadprog.solve_qp(p, -qp.c, c_mat, b_vec)[0]
    return float(0.5 * x @ qp.P @ x + qp.c @ x), x


def test_levels_match_a_level_by_level_reference_and_hold_higher_levels(lbr4p):
    c = _controller(lbr4p, Circle(1.0))
    c.reset(LBR4P_Q0)
    _advance(lbr4p, c, LBR4P_Q0.copy(), 6)
    problem = c.last_problem()
    result = solve_levels(problem, DaqpBackend())
    assert result.failed_level is None
    held = []
    for k, sol in enumerate(result.per_level):
        # the reference holds the levels above exactly (independent rows, ±1e-10 for
        # quadprog's consistency check), as the solve does first
        qp = level_qp(problem, k, held)
        ref_value, _ = _level_optimum(qp)
        value = 0.5 * sol.x @ qp.P @ sol.x + qp.c @ sol.x
        assert value <= ref_value + 1e-7 * max(1.0, abs(ref_value))
        rows = held_rows(problem, k, sol.x, exact=True)
        if rows is not None:
            _, sv, vt = np.linalg.svd(rows[0], full_matrices=False)
            basis = vt[sv > 1e-10 * sv[0]]
            held.append((basis, basis @ sol.x - 1e-10, basis @ sol.x + 1e-10))
    # every lower level keeps the path rows of level 1 within the level's tolerance
    path = problem.levels[0].residuals[0]
    tol = problem.levels[0].tolerance
    path_rows = path.dense(problem.layout)
    first = path_rows @ result.per_level[0].x
    for sol in result.per_level[1:]:
        assert np.max(np.abs(path_rows @ sol.x - first)) <= tol * (1 + 1e-6) + 1e-9


# ----------------------------------------------------------------------------- closed loop
@pytest.mark.parametrize(("kind", "duration"), [("circle", 1.0), ("sinusoid", 2.0)])
def test_keeps_the_path_where_the_thesis_controllers_deform_it(lbr4p, kind, duration):
    from dqcontrol.controllers import PredictiveController

    traj = (Circle if kind == "circle" else Sinusoid)(duration)
    pf = run_kinematic(_controller(lbr4p, traj), LBR4P_Q0).metrics
    assert pf.completed
    assert pf.path_deviation_max_m <= 0.5e-3
    assert pf.position_violations == pf.velocity_violations == pf.acceleration_violations == 0
    thesis = PredictiveController(
        lbr4p, traj, T, num_instants=10, velocity_limits=THESIS_QD_MAX, acceleration_limit=10.0
    )
    assert run_kinematic(thesis, LBR4P_Q0).metrics.path_deviation_max_m > 0.5e-3


def test_a_path_that_turns_the_tool(lbr4p):
    from dqcontrol.dq.algebra import qfrom_axis_angle

    z = np.array([0.0, 0.0, 1.0])
    turns = [qfrom_axis_angle(z, a) for a in (0.0, 0.4, 0.8)]
    traj = WaypointTrajectory(
        [[0.0, 0.0, 0.0], [0.05, 0.05, 0.0], [0.1, 0.0, 0.05]],
        orientations=np.array(turns),
        times_s=[0.0, 1.5, 3.0],
    )
    m = run_kinematic(_controller(lbr4p, traj), LBR4P_Q0).metrics
    assert m.completed
    assert m.path_deviation_max_m <= 0.5e-3
    assert m.rotation_error_max_rad <= 5e-3
    assert m.position_violations == m.velocity_violations == m.acceleration_violations == 0


def test_panda_on_a_custom_path(panda):
    traj = WaypointTrajectory(
        [[0.0, 0.0, 0.0], [0.1, 0.1, 0.0], [0.0, 0.2, 0.05]], times_s=[0.0, 2.0, 4.0]
    )
    c = PathFollowingController(panda, traj, T)
    m = run_kinematic(c, PANDA_Q0).metrics
    assert m.completed
    assert m.path_deviation_max_m <= 0.5e-3
    assert m.position_violations == m.velocity_violations == m.acceleration_violations == 0


def test_unreachable_path_stops_on_it_at_rest(lbr4p):
    # a straight line that leaves the workspace (3 m away)
    traj = WaypointTrajectory([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]], times_s=[0.0, 6.0])
    c = _controller(lbr4p, traj)
    c.reset(LBR4P_Q0)
    q = LBR4P_Q0.copy()
    qds, ss, devs = [], [], []
    for _ in range(240):
        r = c.step(q)
        q = q + T * r.qd_command
        qds.append(r.qd_command)
        ss.append(r.s)
        devs.append(traj_dev(c, lbr4p, q))
    qds = np.array(qds)
    assert ss[-1] < 1e-3
    assert np.max(np.abs(qds[-20:])) < 1e-3  # at rest
    # no chatter: the command does not alternate at the end
    assert np.max(np.abs(np.diff(qds[-40:], axis=0))) < 1e-3
    assert max(devs) <= 0.5e-3
    assert np.all(q >= lbr4p.limits.q_min) and np.all(q <= lbr4p.limits.q_max)


def traj_dev(controller, robot, q) -> float:
    return float(controller.trajectory.path_deviation(translation(robot.pose(q))[None, :])[0])


def test_start_far_from_the_path_converges_without_crossing_a_bound(lbr4p):
    traj = Circle(4.0).anchored_at(lbr4p.pose(LBR4P_Q0))  # the path through the usual start
    q_far = LBR4P_Q0 + np.array([0.1, -0.08, 0.1, 0.1, -0.1, 0.1, 0.0])
    far = traj.path_deviation(translation(lbr4p.pose(q_far))[None, :])[0]
    assert far > 0.02  # the start is centimetres off the path
    c = _controller(lbr4p, traj)
    res = run_kinematic(c, q_far)
    m = res.metrics
    assert m.completed
    assert m.position_violations == m.velocity_violations == m.acceleration_violations == 0
    last = [traj_dev(c, lbr4p, q) for q in res.log.q[-20:]]
    assert max(last) <= 0.5e-3  # on the path again


# ----------------------------------------------------------------------------- bounds
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 10_000),
    speed=st.floats(0.0, 1.0),
    near_limit=st.booleans(),
)
def test_no_command_outside_a_bound(lbr4p, seed, speed, near_limit):
    rng = np.random.default_rng(seed)
    lim = lbr4p.limits
    c = _controller(lbr4p, Circle(1.0), s_max=1.1)
    q = LBR4P_Q0 + rng.uniform(-0.3, 0.3, 7)
    if near_limit:
        j = int(rng.integers(7))
        q[j] = lim.q_max[j] - 0.006 if rng.random() < 0.5 else lim.q_min[j] + 0.006
    qd0 = speed * THESIS_QD_MAX * rng.uniform(-1, 1, 7)
    c.reset(q, qd0)
    qd_prev = qd0
    for _ in range(8):
        r = c.step(q)
        qd = r.qd_command
        assert np.all(np.abs(qd) <= THESIS_QD_MAX + 1e-9)
        assert np.all(np.abs(qd - qd_prev) <= T * 10.0 + 1e-9)
        assert -1e-12 <= r.s <= 1.1 + 1e-12
        q_next = q + T * qd
        inside_before = np.all(q >= lim.q_min + c.position_margin_rad - 1e-12) and np.all(
            q <= lim.q_max - c.position_margin_rad + 1e-12
        )
        conflict = list(r.diagnostics.conflict_joints)
        for j in conflict:  # the box out of reach: change as fast as allowed towards it
            assert abs(abs(qd[j] - qd_prev[j]) - T * 10.0) <= 1e-9
        free = np.setdiff1d(np.arange(7), conflict)
        if inside_before:
            assert np.all(q_next[free] >= lim.q_min[free] + c.position_margin_rad - 1e-9)
            assert np.all(q_next[free] <= lim.q_max[free] - c.position_margin_rad + 1e-9)
        q, qd_prev = q_next, qd


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"num_intervals": 1}, "num_intervals"),
        ({"horizon_s": 0.0}, "horizon_s"),
        ({"horizon_s": -1.0}, "horizon_s"),
        ({"horizon_s": 0.04}, "horizon_s"),
        ({"tuning": "fast"}, "tuning"),
        ({"s_max": 0.5}, "s_max"),
        ({"acceleration_limit": "fast"}, "acceleration_limit"),
        ({"torque_limit_fraction": 1.5}, "torque_limit_fraction"),
    ],
)
def test_bad_parameters_name_themselves(lbr4p, kwargs, name):
    with pytest.raises(ParameterError, match=name):
        _controller(lbr4p, Circle(2.0), **kwargs)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"path_tolerance": 0.0}, "path_tolerance"),
        ({"progress_tolerance": -1.0}, "progress_tolerance"),
        ({"max_linearisations": 0}, "max_linearisations"),
        ({"acceleration_reserve": 1.5}, "acceleration_reserve"),
        ({"trust_radius_rad": float("nan")}, "trust_radius_rad"),
        ({"interval_growth": 0.5}, "interval_growth"),
        ({"interval_growth": "cubic"}, "interval_growth"),
    ],
)
def test_bad_tuning_names_itself(kwargs, name):
    from dqcontrol.controllers.path_following.tuning import PathFollowingTuning

    with pytest.raises(ParameterError, match=name):
        PathFollowingTuning(**kwargs)


def test_last_problem_names_terms_and_limits(lbr4p):
    c = _controller(lbr4p, Circle(2.0))
    with pytest.raises(ParameterError):
        c.last_problem()
    c.reset(LBR4P_Q0)
    c.step(LBR4P_Q0)
    text = c.last_problem().describe()
    for name in ("path_error", "progress", "posture", "velocity", "acceleration_coupling",
                 "predicted_position", "terminal_braking", "trust_region_q"):  # fmt: skip
        assert name in text
    assert c.step(LBR4P_Q0).diagnostics.linearisations >= 1


def test_behind_a_modelled_servo_steady_tracking_takes_one_round(lbr4p):
    """The linearisation check compares the linear and the true error at the prediction's
    own first state: behind a servo lag that state is not ``q + T qd_0``, and comparing at
    the latter would call every linearisation poor (every step running all its rounds)."""
    period, tau = 0.01, 0.004
    c = PathFollowingController(
        lbr4p, Circle(2.0), period, velocity_limits=THESIS_QD_MAX, acceleration_limit=10.0,
        servo_time_constant_s=tau,
    )  # fmt: skip
    q, qd = LBR4P_Q0.copy(), np.zeros(lbr4p.nq)
    c.reset(q)
    decay = np.exp(-period / tau)
    gain = tau * (1.0 - decay)
    rounds = []
    for _ in range(60):  # the servo the prediction models, exactly
        result = c.step(q, qd)
        rounds.append(result.diagnostics.linearisations)
        cmd = result.qd_command
        q, qd = q + (period - gain) * cmd + gain * qd, cmd + (qd - cmd) * decay
    assert np.mean(rounds[5:]) <= 1.1, rounds
    assert c.tuning.max_linearisations > 1  # the check could have added rounds
