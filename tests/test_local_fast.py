"""The single-instant fast path of the local controller (issue 7) equals the general step.

``TrackingController._step_local`` (p = 1, DAQP, constant ``a_max``) computes the bound box
and the whole Hessian in compiled kernels (``joint_box.joint_boxes``,
``qp_cost.local_hessian``, whose ``Gᵀ G`` is the general step's ``qp_cost.gram``)
and calls DAQP through ``DaqpQP.solve_dense``; ``TrackingController._step_general`` is the
plain step every other case uses (and the local step used before). The two must give the
same commands, ``s``, ``σ``, diagnostics and QP (to 1e-12) over whole closed loops, and the
box must equal ``bounds._vp_box`` + ``intersect_acceleration`` bit for bit on random states.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dqcontrol.cli.bench_cmd import load_bench
from dqcontrol.controllers import LocalController
from dqcontrol.controllers.base import StepDiagnostics, StepResult
from dqcontrol.controllers.bounds import _vp_box, braking_constants, intersect_acceleration
from dqcontrol.controllers.qp_daqp import DaqpQP
from dqcontrol.faults.qp_faults import contradictory
from dqcontrol.model import LBR4P_Q0, RobotModel
from dqcontrol.trajectories import Circle, Sinusoid

#: the synthetic serial chains of the benchmark (benchmarks/bench.py)
long_chain_urdf = load_bench().long_chain_urdf

THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
T = 1e-3
TOL = 1e-12


class ReferenceLocal(LocalController):
    """The local controller stepping with the general path only."""

    def _step(self, q, qd):
        return self._step_general(q, qd)


def make(robot, traj, cls=LocalController, period=T, **kw):
    kw.setdefault("velocity_limits", THESIS_VEL if robot.nq == 7 else np.pi)
    kw.setdefault("acceleration_limit", 10.0)
    return cls(robot, traj, period, **kw)


def count_general(ctrl) -> list[int]:
    """Count the calls of ``ctrl._step_general`` (instance attribute around the method)."""
    calls = [0]
    general = ctrl._step_general

    def counted(q, qd):
        calls[0] += 1
        return general(q, qd)

    ctrl._step_general = counted
    return calls


def assert_same(new: StepResult, ref: StepResult, new_ctrl, ref_ctrl, qp: bool = True) -> None:
    """Equal results (to 1e-12), diagnostics, stall bookkeeping and (``qp``) last QPs."""
    assert new.qd_command.shape == ref.qd_command.shape
    for a, b in ((new.qd_command, ref.qd_command), (new.pose, ref.pose), (new.target, ref.target)):
        assert np.abs(a - b).max() <= TOL, (a, b)  # False with a NaN
    assert abs(new.s - ref.s) <= TOL
    assert abs(new.sigma - ref.sigma) <= TOL and abs(new.sigma_next - ref.sigma_next) <= TOL
    assert new.horizon_qd is None and new.horizon_s is None
    assert ref.horizon_qd is None and ref.horizon_s is None
    a, b = new.diagnostics, ref.diagnostics
    assert (a.status, a.iterations, a.fallback, a.relaxed, a.saturated) == (
        b.status, b.iterations, b.fallback, b.relaxed, b.saturated,
    )  # fmt: skip
    assert a.conflict_joints == b.conflict_joints and a.message == b.message
    assert 0.0 <= a.solve_time_s <= a.step_time_s
    assert (new_ctrl._s_applied, new_ctrl._stalled_steps) == (
        ref_ctrl._s_applied, ref_ctrl._stalled_steps,
    )  # fmt: skip
    if qp:
        pa, pb = new_ctrl.last_problem(), ref_ctrl.last_problem()
        for x, y in zip(pa, pb, strict=True):
            np.testing.assert_allclose(x, y, rtol=0, atol=TOL * max(1.0, float(np.abs(y).max())))


def run_pair(robot, traj, steps, q0=LBR4P_Q0, qd0=None, fast=True, after_done=None, **kw):
    """Both controllers fed the same measured ``q`` (the fast one's loop) for ``steps``
    steps, or until ``after_done`` steps past the task's end (at most ``steps``); returns
    the fast controller's results and the controller."""
    new, ref = make(robot, traj, **kw), make(robot, traj, cls=ReferenceLocal, **kw)
    general_calls = count_general(new)
    q = np.array(q0, dtype=float)
    new.reset(q, qd0)
    ref.reset(q, qd0)
    results = []
    past_end = 0
    most_stalled = 0
    for k in range(steps):
        r_new, r_ref = new.step(q), ref.step(q)
        assert_same(r_new, r_ref, new, ref, qp=k % 10 == 0)  # the QPs at every 10th step
        results.append(r_new)
        most_stalled = max(most_stalled, new._stalled_steps)
        q = q + new.period_s * r_new.qd_command
        if after_done is not None and new.done:
            past_end += 1
            if past_end > after_done:
                break
    if fast:
        assert general_calls[0] == 0, "the fast path was not taken"
    else:
        assert general_calls[0] == len(results), "the fast path was taken where it does not apply"
    new.most_stalled = most_stalled
    return results, new


# ------------------------------------------------------------------ closed loops


@pytest.mark.parametrize(
    "traj", [Circle(1.0), Circle(2.0), Circle(8.0), Sinusoid(2.0)],
    ids=["circle1", "circle2", "circle8", "sinusoid2"],
)  # fmt: skip
def test_closed_loop_tasks(lbr4p, traj):
    """The whole task and 50 steps past its end (the target held)."""
    results, ctrl = run_pair(lbr4p, traj, 20000, after_done=50)
    assert ctrl.done and len(results) < 20000


@pytest.mark.parametrize(
    "kw",
    [
        {"braking_aware": False},
        {"scaling": False},
        {"measurement_delay_periods": 2},
        {"task_weight": 3.0, "regularization": 1e-5, "scaling_weight": 2e-3},
        {"acceleration_limit": np.array([5.0, 8, 10, 12, 20, 30, 40])},
    ],
    ids=["no_braking", "no_scaling", "delay2", "weights", "per_joint_a_max"],
)
def test_closed_loop_variants(lbr4p, kw):
    run_pair(lbr4p, Circle(2.0), 1200, **kw)


def test_unreachable_circle_engages_the_stall_damping(lbr4p):
    results, ctrl = run_pair(lbr4p, Circle(2.0, radius_m=0.4), 3000)
    # 0.5 s of s < 0.05, then the damping acts (on the Hessian, compared above) for a while
    assert ctrl._stall_steps == 500 and ctrl.most_stalled > 1000


def test_start_near_and_beyond_the_limits(lbr4p):
    """Moving fast towards limits (acceleration/position conflicts, braking bound), one
    joint starting beyond its limit."""
    lim = lbr4p.limits
    q0 = LBR4P_Q0.copy()
    q0[[0, 3]] = lim.q_max[[0, 3]] - [0.02, 0.004]
    q0[5] = lim.q_min[5] - 0.01  # beyond the limit (and the 5 mrad margin)
    qd0 = np.zeros(7)
    qd0[[0, 3]] = THESIS_VEL[[0, 3]]  # towards the upper limits at full speed
    results, _ = run_pair(lbr4p, Circle(2.0), 600, q0=q0, qd0=qd0)
    assert sum(bool(r.diagnostics.conflict_joints) for r in results) >= 3


@pytest.mark.parametrize(
    "kw",
    [{"acceleration_limit": "dynamics"}, {"solver": "osqp"}],
    ids=["dynamics", "osqp"],
)
def test_cases_outside_the_fast_path_use_the_general_step(lbr4p, kw):
    ctrl = make(lbr4p, Circle(2.0), **kw)
    assert ctrl._local_qp is None
    run_pair(lbr4p, Circle(2.0), 300, fast=False, **kw)


@pytest.mark.parametrize("n", [1, 3, 10])
def test_other_joint_counts(n):
    robot = RobotModel.from_urdf(long_chain_urdf(n), "flange")
    q0 = np.random.default_rng(n).uniform(-0.5, 0.5, n)
    run_pair(robot, Circle(2.0, radius_m=0.05), 400, q0=q0)


def test_table1_period(lbr4p):
    """T = 50 ms (the thesis's Table 1): larger steps, more bound activity."""
    run_pair(lbr4p, Circle(2.0), 200, period=0.05)
    run_pair(lbr4p, Sinusoid(2.0), 200, period=0.05)


# ------------------------------------------------------------------ failures, unusual states


def test_qp_failure_falls_back_as_before(lbr4p):
    """DAQP stopped after one iteration: the safe fallback (brake within a_max, s = 0)."""
    kw = {"solver_settings": {"iter_limit": 1}}
    results, _ = run_pair(lbr4p, Circle(2.0), 200, q0=LBR4P_Q0, qd0=0.5 * THESIS_VEL, **kw)
    failed = [r for r in results if r.diagnostics.fallback]
    assert failed, "no QP failed"
    for r in failed:
        assert r.s == 0.0 and r.diagnostics.message.startswith("QP failed (iteration_limit)")


@pytest.mark.parametrize("what", ["q_min", "qd_prev"])
def test_nan_bounds_go_through_the_checked_wrapper(lbr4p, what):
    """A NaN limit or previous command: the general step, whose wrapper refuses the bounds
    (``invalid_bounds``) and falls back, exactly as before."""
    new, ref = make(lbr4p, Circle(2.0)), make(lbr4p, Circle(2.0), cls=ReferenceLocal)
    calls = count_general(new)
    for ctrl in (new, ref):
        ctrl.reset(LBR4P_Q0)
        ctrl.step(LBR4P_Q0)
        if what == "q_min":
            ctrl.q_min = ctrl.q_min.copy()
            ctrl.q_min[2] = np.nan
        else:
            ctrl.qd_prev = ctrl.qd_prev.copy()
            ctrl.qd_prev[4] = np.nan
    r_new, r_ref = new.step(LBR4P_Q0), ref.step(LBR4P_Q0)
    assert calls[0] == 1
    assert r_new.diagnostics.status.startswith("invalid_bounds")
    assert r_new.diagnostics.status == r_ref.diagnostics.status and r_new.diagnostics.fallback
    np.testing.assert_array_equal(r_new.qd_command, r_ref.qd_command)  # NaN where ref has


def test_contradictory_bounds_still_reach_the_checked_wrapper(lbr4p):
    """The fault campaign's proxy QP replaces ``qp``: the general step, refused bounds."""
    ctrl = contradictory(LocalController)(lbr4p, Circle(2.0), T, window_steps=(2, 4))
    calls = count_general(ctrl)
    ctrl.reset(LBR4P_Q0)
    q = LBR4P_Q0.copy()
    statuses = []
    for _ in range(6):
        res = ctrl.step(q)
        statuses.append(res.diagnostics.status)
        q = q + T * res.qd_command
    assert calls[0] == 6
    assert [s.startswith("invalid_bounds") for s in statuses] == [0, 0, 1, 1, 0, 0]
    assert ctrl.qp.false_successes == 0


def test_parameters_changed_after_construction_are_used(lbr4p):
    """qd_max (reassigned and in place), q_min/q_max (faults.analysis.position_margin), K,
    λ1, T and the braking switch are read at every step, as by the general step."""
    lim = lbr4p.limits
    new, ref = make(lbr4p, Circle(2.0)), make(lbr4p, Circle(2.0), cls=ReferenceLocal)
    q = LBR4P_Q0.copy()
    for ctrl in (new, ref):
        ctrl.reset(q)
    changes = [
        lambda c: setattr(c, "qd_max", 0.5 * THESIS_VEL),
        lambda c: c.qd_max.__setitem__(2, 0.05),  # in place
        lambda c: (setattr(c, "q_min", lim.q_min + 0.3), setattr(c, "q_max", lim.q_max - 0.3)),
        lambda c: setattr(c, "gain_per_s", 25.0),
        lambda c: setattr(c, "task_weight", 2.5),
        lambda c: setattr(c, "braking_aware", False),
        lambda c: setattr(c, "period_s", 2e-3),
    ]
    for change in changes:
        for ctrl in (new, ref):
            change(ctrl)
        for _ in range(60):
            r_new, r_ref = new.step(q), ref.step(q)
            assert_same(r_new, r_ref, new, ref)
            q = q + new.period_s * r_new.qd_command


def test_result_objects_without_the_fast_fill(lbr4p, monkeypatch):
    """Where the dataclasses would not be built by filling ``__dict__``, their own
    constructors; either way the objects equal the general step's."""
    new, ref = make(lbr4p, Circle(2.0)), make(lbr4p, Circle(2.0), cls=ReferenceLocal)
    assert new._new_result is not StepResult  # the fast fill applies to these dataclasses
    new._new_diag, new._new_result = StepDiagnostics, StepResult
    q = LBR4P_Q0.copy()
    new.reset(q)
    ref.reset(q)
    for _ in range(20):
        r_new, r_ref = new.step(q), ref.step(q)
        assert_same(r_new, r_ref, new, ref)
        q = q + T * r_new.qd_command
    fast = make(lbr4p, Circle(2.0))
    fast.reset(q)
    r = fast.step(q)
    ignore = {"step_time_s", "solve_time_s"}
    d_fast = {k: v for k, v in vars(r.diagnostics).items() if k not in ignore}
    d_ctor = {k: v for k, v in vars(r_ref.diagnostics).items() if k not in ignore}
    assert d_fast.keys() == d_ctor.keys()
    assert vars(r).keys() == vars(r_ref).keys()
    assert dataclasses.replace(r, diagnostics=r_ref.diagnostics).diagnostics is r_ref.diagnostics


# ------------------------------------------------------------------ the box, bit for bit


def random_state(rng, n, q_min, q_max, qd_max, a_max, period, braking):
    """Positions inside, near and beyond the limits and right at the fast path's ``far``
    distance; previous commands up to 1.5 qd_max (acceleration conflicts)."""
    reach = period * qd_max + (qd_max**2 / (2 * a_max) if braking else 0.0)
    mode = rng.integers(0, 4, n)
    side = rng.random(n) < 0.5
    dist = np.where(
        mode == 0,
        rng.uniform(-0.1, 0.2, n),
        np.where(mode == 1, reach * (1.0 + rng.uniform(-1e-5, 1e-5, n)), 0.0),
    )
    q = np.where(side, q_max - dist, q_min + dist)
    q = np.where(mode >= 2, rng.uniform(q_min, q_max), q)
    qd_prev = rng.uniform(-1.5, 1.5, n) * qd_max
    return q, qd_prev


@pytest.mark.parametrize("seed", range(12))
def test_box_equals_the_bounds_functions_bit_for_bit(lbr4p, seed):
    """12 controllers × 250 seeded states: the QP's bounds and the conflict joints are
    ``_vp_box`` + ``intersect_acceleration`` exactly (3000 states in all)."""
    rng = np.random.default_rng(seed)
    n = lbr4p.nq
    qd_max = np.exp(rng.uniform(np.log(0.05), np.log(10.0), n))
    a_max = np.exp(rng.uniform(np.log(0.5), np.log(100.0), n))
    period = float(rng.choice([1e-3, 4e-3, 0.01, 0.05]))
    braking = bool(seed % 4)
    ctrl = make(
        lbr4p, Circle(2.0), period=period, velocity_limits=qd_max, acceleration_limit=a_max,
        braking_aware=braking,
    )  # fmt: skip
    calls = count_general(ctrl)
    ctrl.reset(LBR4P_Q0)
    brake = braking_constants(a_max, period) if braking else None
    for _ in range(250):
        q, qd_prev = random_state(rng, n, ctrl.q_min, ctrl.q_max, qd_max, a_max, period, braking)
        ctrl.qd_prev = qd_prev
        res = ctrl.step(q)
        lo, hi = _vp_box(q, ctrl.q_min, ctrl.q_max, qd_max, period, brake)
        box = intersect_acceleration(lo, hi, qd_prev, period * a_max)
        prob = ctrl.last_problem()
        np.testing.assert_array_equal(prob.lower[:n], box.lower)
        np.testing.assert_array_equal(prob.upper[:n], box.upper)
        assert res.diagnostics.conflict_joints == tuple(np.flatnonzero(box.conflict).tolist())
        if not res.diagnostics.fallback:
            np.testing.assert_array_equal(res.qd_command, box.project(res.qd_command))
    assert calls[0] == 0


# ------------------------------------------------------------------ the DAQP entry


def test_solve_dense_equals_solve():
    """``solve_dense`` (whole H, checked bounds) and ``solve`` (stored values, checks) give
    the same solutions, through setups, updates, a new f and failures."""
    import scipy.sparse as sp

    m = 4
    pattern = sp.csc_matrix(np.triu(np.ones((m, m))))
    a_matrix = sp.identity(m, format="csc")
    fast, ref = DaqpQP(pattern, a_matrix), DaqpQP(pattern, a_matrix)
    rows, cols = np.triu_indices(m)
    order = np.lexsort((rows, cols))  # CSC order of the upper triangle
    rng = np.random.default_rng(5)
    c = np.array([0.1, -0.2, 0.0, -2e-3])
    for k in range(300):
        g = rng.normal(size=(6, m))
        h = g.T.dot(g) + 1e-6 * np.eye(m)
        lower = rng.uniform(-1.0, 0.0, m)
        upper = lower + rng.uniform(0.0, 1.0, m)
        if k % 50 == 10:
            upper[1] = lower[1]  # a collapsed box
        if k % 100 == 60:
            c = c + 0.01  # a new f
        if k % 70 == 30:
            h = -h  # not convex: both fail and rebuild
        x_fast, ok, status, iterations, t = fast.solve_dense(h.copy(), c, lower, upper)
        sol = ref.solve(h[rows[order], cols[order]], c, lower, upper)
        assert (ok, status, iterations) == (sol.ok, sol.status, sol.iterations)
        assert t >= 0.0
        if ok:
            np.testing.assert_array_equal(x_fast, sol.x)
        else:
            assert x_fast is None and sol.x is None
