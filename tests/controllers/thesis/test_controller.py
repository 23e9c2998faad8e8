"""The thesis's QP controllers (dqcontrol/controllers/thesis/controller.py, docs/theory.md
§4–5), local and predictive: QP solutions against an independent solver (quadprog), hard
bounds under random states, time scaling, varying orientation, strict priority levels
against a level-by-level reference, the default backend, bad parameters."""

from __future__ import annotations

import numpy as np
import pytest
import quadprog
from controllers.core.test_levels import level_cost, reference_levels
from hypothesis import given, settings
from hypothesis import strategies as st

from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
    ProportionalController,
    command_box,
)
from dqcontrol.controllers.backends import DaqpBackend
from dqcontrol.controllers.core.levels import solve_levels
from dqcontrol.controllers.thesis.controller import DEFAULT_SOLVER
from dqcontrol.dq import qconj, qfrom_axis_angle, qmul, rotation_angle, translation
from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle, Sinusoid, WaypointTrajectory

T = 0.05
#: The thesis's controller velocity bound (eq. 4.13) and constant acceleration bound.
THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
THESIS_ACC = 10.0


def make(kind, robot, traj, **kw):
    kw.setdefault("velocity_limits", THESIS_VEL)
    kw.setdefault("acceleration_limit", THESIS_ACC)
    if kind == "local":
        return LocalController(robot, traj, T, **kw)
    if kind == "p6":
        return PredictiveController(robot, traj, T, num_instants=6, **kw)
    if kind == "p10":
        return PredictiveController(robot, traj, T, num_instants=10, **kw)
    if kind == "noscale":
        return PredictiveNoScalingController(robot, traj, T, num_instants=6, **kw)
    if kind == "proportional":
        return ProportionalController(robot, traj, T, **kw)
    raise ValueError(kind)


def reference_qp(problem):
    """Independent dense active-set solution (quadprog) of the controller's QP."""
    p_mat = problem.P + 1e-13 * np.eye(problem.c.size)
    lo, up, a = problem.lower, problem.upper, problem.A
    fl, fu = np.isfinite(lo), np.isfinite(up)
    eq = fl & fu & (lo == up)
    rows = [a[eq], a[fl & ~eq], -a[fu & ~eq]]
    rhs = [lo[eq], lo[fl & ~eq], -up[fu & ~eq]]
    x = quadprog.solve_qp(p_mat, -problem.c, np.vstack(rows).T, np.concatenate(rhs), int(eq.sum()))[
        0
    ]
    return x


# --------------------------------------------------------------------------- QP vs reference
SOLVERS = ["osqp", "daqp"]


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("kind", ["local", "p6", "p10", "noscale"])
@pytest.mark.parametrize("traj_cls,duration", [(Circle, 1.0), (Sinusoid, 2.0)])
def test_qp_matches_independent_solution(lbr4p, kind, traj_cls, duration, solver):
    ctrl = make(kind, lbr4p, traj_cls(duration), solver=solver)
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    checked = 0
    for k in range(40):
        res = ctrl.step(q)
        q = q + T * res.qd_command
        if k % 8 != 3:
            continue
        prob = ctrl.last_problem()
        xr = reference_qp(prob)
        n = lbr4p.nq
        assert not res.diagnostics.fallback
        # the applied command and scaling equal the reference solution
        np.testing.assert_allclose(res.qd_command, xr[:n], atol=2e-5)
        assert res.s == pytest.approx(min(max(xr[n], 0.0), 1.0), abs=2e-6)
        # same optimal objective, and the solver's full solution is feasible
        z = (
            np.concatenate([res.horizon_qd, res.horizon_s[:, None]], axis=1).ravel()
            if (res.horizon_qd is not None)
            else np.concatenate([res.qd_command, [res.s]])
        )

        def f(v, prob=prob):
            return 0.5 * v @ prob.P @ v + prob.c @ v

        assert f(z) == pytest.approx(f(xr), abs=1e-8)
        az = prob.A @ z
        assert np.all(az >= prob.lower - 1e-6) and np.all(az <= prob.upper + 1e-6)
        checked += 1
    assert checked >= 4


# --------------------------------------------------------------------------- hard bounds
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    kind=st.sampled_from(["local", "p6", "noscale"]),
    near_limit=st.booleans(),
    fast=st.booleans(),
    prev_at_acc_limit=st.booleans(),
    dynamic=st.booleans(),
    solver=st.sampled_from(SOLVERS),
)
def test_commands_never_cross_a_bound(
    lbr4p, seed, kind, near_limit, fast, prev_at_acc_limit, dynamic, solver
):
    rng = np.random.default_rng(seed)
    lim = lbr4p.limits
    q = rng.uniform(lim.q_min + 0.05, lim.q_max - 0.05)
    if near_limit:
        j = rng.integers(0, 7, size=3)
        side = rng.choice([-1.0, 1.0], size=3)
        q[j] = np.where(side > 0, lim.q_max[j], lim.q_min[j]) - side * rng.uniform(0, 0.02, 3)
    qd_prev = rng.uniform(-1, 1, 7) * THESIS_VEL * (0.9 if fast else 0.2)
    kw = {"acceleration_limit": "dynamics"} if dynamic else {}
    ctrl = make(kind, lbr4p, Circle(1.0), solver=solver, **kw)
    ctrl.reset(q, qd0=qd_prev)
    a_max = (
        lbr4p.acceleration_limits(q, floor_rad_s2=ctrl.acceleration_floor,
                                  cap_rad_s2=ctrl.acceleration_cap)
        if dynamic else np.full(7, THESIS_ACC)
    )  # fmt: skip
    if prev_at_acc_limit:
        ctrl.qd_prev = np.clip(
            qd_prev + T * a_max * rng.choice([-1, 1], 7), -THESIS_VEL, THESIS_VEL
        )
    for _ in range(3):
        prev = ctrl.qd_prev.copy()
        res = ctrl.step(q)
        qd = res.qd_command
        box = command_box(q, prev, lim.q_min, lim.q_max, THESIS_VEL, a_max, T)
        tol = 1e-9
        assert 0.0 <= res.s <= 1.0
        assert np.all(np.abs(qd - prev) <= T * a_max + tol)  # acceleration: always
        ok = ~box.conflict
        assert np.all(np.abs(qd[ok]) <= THESIS_VEL[ok] + tol)  # velocity
        assert np.all(q[ok] + T * qd[ok] <= lim.q_max[ok] + tol)  # position, one period
        assert np.all(q[ok] + T * qd[ok] >= lim.q_min[ok] - tol)
        # conflicting joints brake as hard as the acceleration bound allows
        for j in np.flatnonzero(box.conflict):
            assert abs(qd[j] - prev[j]) == pytest.approx(T * a_max[j], abs=1e-9)
        q = q + T * qd
        if dynamic:
            a_max = lbr4p.acceleration_limits(
                q, floor_rad_s2=ctrl.acceleration_floor, cap_rad_s2=ctrl.acceleration_cap
            )


@pytest.mark.parametrize("kind", ["local", "p6"])
def test_whole_runs_have_no_violation(lbr4p, kind):
    res = run_kinematic(make(kind, lbr4p, Circle(1.0)), LBR4P_Q0)
    m = res.metrics
    assert (m.position_violations, m.velocity_violations, m.acceleration_violations) == (0, 0, 0)
    assert not m.nan_seen


# --------------------------------------------------------------------------- time scaling
@pytest.mark.parametrize("kind", ["local", "p10"])
def test_slow_task_keeps_full_speed_and_converges(lbr4p, kind):
    res = run_kinematic(make(kind, lbr4p, Circle(8.0)), LBR4P_Q0)
    m = res.metrics
    assert m.completed and m.s_mean > 0.99
    assert m.execution_time_s <= 8.0 * 1.02 + T
    assert m.e_max < 5e-4 and m.path_deviation_max_m < 1e-3


@pytest.mark.parametrize("kind", ["local", "p10"])
def test_infeasible_timing_scales_down_and_keeps_the_path(lbr4p, kind):
    res = run_kinematic(make(kind, lbr4p, Circle(1.0)), LBR4P_Q0)
    m = res.metrics
    assert m.completed and res.log.sigma[-1] + T * res.log.s[-1] >= 1.0 - 1e-12
    assert m.s_mean < 0.9 and res.log.s.min() < 0.6
    assert m.execution_time_s > 1.2
    assert np.all(np.diff(res.log.sigma) >= 0.0)
    # the path is kept: a few mm at most on a 100 mm circle driven beyond its limits
    assert m.path_deviation_mean_m < 0.015


# --------------------------------------------------------------------------- varying orientation
def turning_waypoints() -> WaypointTrajectory:
    """Four waypoints over 6 s along which the orientation turns."""
    pos = np.array([[0, 0, 0], [0.05, 0.05, 0.02], [0.1, 0.0, -0.03], [0.12, -0.06, 0.0]])
    rot = np.array(
        [qfrom_axis_angle([0, 0, 1], 0.0), qfrom_axis_angle([0, 0, 1], 0.3),
         qfrom_axis_angle([1, 0, 0], 0.25), qfrom_axis_angle([0, 1, 1], -0.3)]
    )  # fmt: skip
    return WaypointTrajectory(pos, rot, times_s=np.array([0.0, 2.0, 4.0, 6.0]))


@pytest.mark.parametrize("kind", ["local", "p6", "noscale"])
def test_varying_orientation_is_tracked(lbr4p, kind):
    traj = turning_waypoints()
    assert_tracked_and_turned(run_kinematic(make(kind, lbr4p, traj), LBR4P_Q0))


def assert_tracked_and_turned(res) -> None:
    """The run of :func:`turning_waypoints` completed, tracked within 0.01 rad and 2 mm, and
    the tool turned by more than 0.2 rad and moved by more than 0.1 m."""
    m = res.metrics
    assert m.completed
    assert m.rotation_error_max_rad < 0.01 and m.translation_error_max_m < 2e-3
    # the orientation did change along the run
    turned = rotation_angle(qmul(qconj(res.log.pose[0, :4]), res.log.pose[-1, :4]))
    assert turned > 0.2
    assert np.linalg.norm(translation(res.log.pose[-1]) - translation(res.log.pose[0])) > 0.1


# --------------------------------------------------------------------------- strict priority
@pytest.mark.parametrize("cls", [LocalController, PredictiveController])
def test_strict_priority_of_the_thesis_controllers(lbr4p, cls):
    """``priority="strict"``: three levels (tracking ≻ scaling ≻ damping), the same limits;
    each level matches the level-by-level reference and the applied command keeps every
    bound."""
    kw = {"num_instants": 6} if cls is PredictiveController else {}
    ctrl = cls(lbr4p, Circle(1.0), 0.05, velocity_limits=THESIS_VEL, acceleration_limit=10.0,
               priority="strict", **kw)  # fmt: skip
    assert [lev.name for lev in ctrl.levels] == ["tracking", "scaling", "damping"]
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    for k in range(12):
        res = ctrl.step(q)
        assert not res.diagnostics.fallback
        problem = ctrl.last_problem()
        n = lbr4p.nq
        assert np.all(res.qd_command >= problem.lower[:n]) and np.all(
            res.qd_command <= problem.upper[:n]
        )
        if k % 4 == 3:
            result = solve_levels(problem, DaqpBackend())
            reference = reference_levels(problem)
            for level, (sol, ref) in enumerate(zip(result.per_level, reference, strict=True)):
                ours, theirs = level_cost(problem, level, sol.x), level_cost(problem, level, ref)
                assert ours == pytest.approx(theirs, rel=1e-5, abs=1e-9)
        q = q + 0.05 * res.qd_command
    assert res.s < 1.0  # the 1 s circle is beyond the bounds: the scaling gives way


# --------------------------------------------------------------------------- parameters
@pytest.mark.parametrize(
    "kwargs,fragment",
    [
        ({"gain_per_s": -1.0}, "gain_per_s"),
        ({"task_weight": 0.0}, "task_weight"),
        ({"scaling_weight": -1.0}, "scaling_weight"),
        ({"acceleration_limit": "fast"}, "acceleration_limit"),
        ({"acceleration_limit": -3.0}, "acceleration_limit"),
        ({"velocity_limits": 0.0}, "velocity_limits"),
        ({"phase_prediction": "magic"}, "phase_prediction"),
        ({"num_instants": 1}, "p must be an integer ≥ 2"),
        ({"horizon_s": 0.0}, "tau_p must be > 0"),
    ],
)
def test_bad_parameters_are_named(lbr4p, kwargs, fragment):
    with pytest.raises(ParameterError, match=fragment):
        PredictiveController(lbr4p, Circle(1.0), T, **kwargs)


def test_strict_priority_needs_strictly_convex_levels(lbr4p):
    with pytest.raises(ParameterError, match="strict"):
        LocalController(lbr4p, Circle(1.0), 0.05, priority="strict", regularization=0.0)
    with pytest.raises(ParameterError, match="priority must be"):
        LocalController(lbr4p, Circle(1.0), 0.05, priority="lexicographic")


def test_default_solver_rule(lbr4p):
    assert DEFAULT_SOLVER == "daqp"
    # settings never pick the backend: OSQP's given to the default are refused
    traj = Circle(2.0)
    with pytest.raises(ParameterError, match="DAQP has no setting.*max_iter"):
        LocalController(lbr4p, traj, period_s=0.05, solver_settings={"max_iter": 1})
    ctrl = LocalController(
        lbr4p, traj, period_s=0.05, solver="osqp", solver_settings={"max_iter": 1}
    )
    assert type(ctrl.backend).__name__ == "OsqpBackend"
