"""The local controller's QP on each backend against a reference solve (docs/theory.md §7.5).

The local controller's QP has one block and bounds only: the DAQP backend hands DAQP the
whole Hessian (``DaqpBlocks``'s dense form), OSQP (refined) is the other backend. Over whole
closed loops, every QP a backend solves is solved again by an independent dense active-set
solver (quadprog) and the two optima must agree; the bounds the backend receives must be
``bounds._vp_box`` + ``intersect_acceleration`` bit for bit on random states.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import quadprog

from dqcontrol.cli.bench_cmd import load_bench
from dqcontrol.controllers import LocalController, command_box
from dqcontrol.controllers.backends import DaqpBackend, ForwardingBackend
from dqcontrol.controllers.base import StepDiagnostics, StepResult
from dqcontrol.controllers.core.bounds import _vp_box, braking_constants, intersect_acceleration
from dqcontrol.faults.qp_faults import contradictory
from dqcontrol.model import LBR4P_Q0, RobotModel
from dqcontrol.trajectories import Circle, Sinusoid

#: the synthetic serial chains of the benchmark (benchmarks/bench.py)
long_chain_urdf = load_bench().long_chain_urdf

THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
T = 1e-3
#: Backend vs reference: the optimal value (relative) and the solution [rad/s, -]; the
#: solution differs most along the redundant direction, which only μ = 1e-6 fixes.
VALUE_TOL = 1e-10
X_TOL = 1e-6
#: DAQP's primal tolerance (its default): rows may be crossed by that much (the applied
#: command is clipped to its box).
FEASIBILITY_TOL = 1e-6


def reference_solve(qp) -> tuple[np.ndarray, object]:
    """quadprog on the block QP written densely (equal bounds as equalities)."""
    dense = qp.dense()
    p_mat = dense.P + 1e-13 * np.eye(dense.c.size)
    lo, up, a = dense.lower, dense.upper, dense.A
    fl, fu = np.isfinite(lo), np.isfinite(up)
    eq = fl & fu & (lo == up)
    rows = [a[eq], a[fl & ~eq], -a[fu & ~eq]]
    rhs = [lo[eq], lo[fl & ~eq], -up[fu & ~eq]]
    x = quadprog.solve_qp(p_mat, -dense.c, np.vstack(rows).T, np.concatenate(rhs), int(eq.sum()))
    return x[0], dense


class Referee(ForwardingBackend):
    """Wraps a controller's backend: every QP it solves is solved again by quadprog and
    compared; the last QP and solution are kept."""

    def __init__(self, inner) -> None:
        super().__init__(inner)
        self.checked = 0
        self.last = None

    def solve_blocks(self, qp):
        sol = self.inner.solve_blocks(qp)
        self.last = (qp, sol)
        if sol.ok:
            x_ref, dense = reference_solve(qp)

            def f(v):
                return 0.5 * v @ dense.P @ v + dense.c @ v

            scale = max(1.0, abs(f(x_ref)))
            assert abs(f(sol.x) - f(x_ref)) <= VALUE_TOL * scale
            assert np.abs(sol.x - x_ref).max() <= X_TOL
            ax = dense.A @ sol.x
            tol = FEASIBILITY_TOL
            assert np.all(ax >= dense.lower - tol) and np.all(ax <= dense.upper + tol)
            self.checked += 1
        return sol


def make(robot, traj, period=T, **kw):
    kw.setdefault("velocity_limits", THESIS_VEL if robot.nq == 7 else np.pi)
    kw.setdefault("acceleration_limit", 10.0)
    ctrl = LocalController(robot, traj, period, **kw)
    ctrl.qp = Referee(ctrl.qp)
    return ctrl


def stall_term(ctrl):
    return next(t for t in ctrl.levels[0].terms if t.name == "stall_damping")


def check_step(ctrl, res: StepResult) -> None:
    """The applied command is the backend's solution clipped to the applied box."""
    qp, sol = ctrl.qp.last
    n = ctrl.n
    assert res.horizon_qd is None and res.horizon_s is None
    assert 0.0 <= res.diagnostics.solve_time_s <= res.diagnostics.step_time_s
    if sol.ok:
        assert not res.diagnostics.fallback
        np.testing.assert_array_equal(
            res.qd_command, np.clip(sol.x[:n], qp.lower[:n], qp.upper[:n])
        )
        if ctrl.scaling:
            assert res.s == min(max(sol.x[n], 0.0), 1.0)
    else:
        assert res.diagnostics.fallback and res.s == 0.0
        safe = np.minimum(np.maximum(np.zeros(n), qp.lower[:n]), qp.upper[:n])
        np.testing.assert_array_equal(res.qd_command, safe)


def run(robot, traj, steps, q0=LBR4P_Q0, qd0=None, after_done=None, **kw):
    """A closed loop of ``steps`` steps (or until ``after_done`` steps past the task's end),
    every QP checked against the reference; the results and the controller."""
    ctrl = make(robot, traj, **kw)
    q = np.array(q0, dtype=float)
    ctrl.reset(q, qd0)
    results = []
    past_end = 0
    most_stalled = 0
    for _ in range(steps):
        res = ctrl.step(q)
        check_step(ctrl, res)
        results.append(res)
        most_stalled = max(most_stalled, stall_term(ctrl).stalled_steps if ctrl.scaling else 0)
        q = q + ctrl.period_s * res.qd_command
        if after_done is not None and ctrl.done:
            past_end += 1
            if past_end > after_done:
                break
    assert ctrl.qp.checked > 0 or any(r.diagnostics.fallback for r in results)
    ctrl.most_stalled = most_stalled
    return results, ctrl


# ------------------------------------------------------------------ closed loops


@pytest.mark.parametrize(
    "traj", [Circle(1.0), Circle(2.0), Circle(8.0), Sinusoid(2.0)],
    ids=["circle1", "circle2", "circle8", "sinusoid2"],
)  # fmt: skip
def test_closed_loop_tasks(lbr4p, traj):
    """The whole task and 50 steps past its end (the target held)."""
    results, ctrl = run(lbr4p, traj, 20000, after_done=50)
    assert ctrl.done and len(results) < 20000
    assert ctrl.qp.inner.form == "dense"


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
    run(lbr4p, Circle(2.0), 1200, **kw)


def test_unreachable_circle_engages_the_stall_damping(lbr4p):
    results, ctrl = run(lbr4p, Circle(2.0, radius_m=0.4), 3000)
    # 0.5 s of s < 0.05, then the damping acts (on the Hessian, checked above) for a while
    assert stall_term(ctrl).delay_steps == 500 and ctrl.most_stalled > 1000


def test_start_near_and_beyond_the_limits(lbr4p):
    """Moving fast towards limits (acceleration/position conflicts, braking bound), one
    joint starting beyond its limit."""
    lim = lbr4p.limits
    q0 = LBR4P_Q0.copy()
    q0[[0, 3]] = lim.q_max[[0, 3]] - [0.02, 0.004]
    q0[5] = lim.q_min[5] - 0.01  # beyond the limit (and the 5 mrad margin)
    qd0 = np.zeros(7)
    qd0[[0, 3]] = THESIS_VEL[[0, 3]]  # towards the upper limits at full speed
    results, _ = run(lbr4p, Circle(2.0), 600, q0=q0, qd0=qd0)
    assert sum(bool(r.diagnostics.conflict_joints) for r in results) >= 3


@pytest.mark.parametrize(
    "kw",
    [{"acceleration_limit": "dynamics"}, {"solver": "osqp"}],
    ids=["dynamics", "osqp"],
)
def test_other_backends_and_bounds(lbr4p, kw):
    _, ctrl = run(lbr4p, Circle(2.0), 300, **kw)
    assert ctrl.qp.inner.name == kw.get("solver", "daqp")


@pytest.mark.parametrize("n", [1, 3, 10])
def test_other_joint_counts(n):
    robot = RobotModel.from_urdf(long_chain_urdf(n), "flange")
    q0 = np.random.default_rng(n).uniform(-0.5, 0.5, n)
    run(robot, Circle(2.0, radius_m=0.05), 400, q0=q0)


def test_table1_period(lbr4p):
    """T = 50 ms (the thesis's Table 1): larger steps, more bound activity."""
    run(lbr4p, Circle(2.0), 200, period=0.05)
    run(lbr4p, Sinusoid(2.0), 200, period=0.05)


# ------------------------------------------------------------------ failures, unusual states


def test_qp_failure_falls_back(lbr4p):
    """DAQP stopped after one iteration: the safe fallback (brake within a_max, s = 0)."""
    kw = {"solver_settings": {"iter_limit": 1}}
    results, _ = run(lbr4p, Circle(2.0), 200, q0=LBR4P_Q0, qd0=0.5 * THESIS_VEL, **kw)
    failed = [r for r in results if r.diagnostics.fallback]
    assert failed, "no QP failed"
    for r in failed:
        assert r.s == 0.0 and r.diagnostics.message.startswith("QP failed (iteration_limit)")


@pytest.mark.parametrize("what", ["q_min", "qd_prev"])
def test_nan_bounds_are_refused_by_the_backend(lbr4p, what):
    """A NaN limit or previous command: the backend refuses the bounds (``invalid_bounds``)
    and the step falls back to the point of the (NaN) box closest to zero."""
    ctrl = make(lbr4p, Circle(2.0))
    ctrl.reset(LBR4P_Q0)
    ctrl.step(LBR4P_Q0)
    if what == "q_min":
        ctrl.q_min = ctrl.q_min.copy()
        ctrl.q_min[2] = np.nan
    else:
        ctrl.qd_prev = ctrl.qd_prev.copy()
        ctrl.qd_prev[4] = np.nan
    prev = ctrl.qd_prev.copy()
    res = ctrl.step(LBR4P_Q0)
    assert res.diagnostics.status.startswith("invalid_bounds") and res.diagnostics.fallback
    box = command_box(LBR4P_Q0, prev, ctrl.q_min, ctrl.q_max, ctrl.qd_max, ctrl.a_const, T, True)
    np.testing.assert_array_equal(res.qd_command, box.project(np.zeros(7)))  # NaN where NaN


def test_contradictory_bounds_reach_the_production_backend(lbr4p):
    """The fault campaign's wrapper sits in front of the production backend (the dense form
    of DAQP): the corrupted bounds are refused there."""
    ctrl = contradictory(LocalController)(lbr4p, Circle(2.0), T, window_steps=(2, 4))
    ctrl.reset(LBR4P_Q0)
    q = LBR4P_Q0.copy()
    statuses = []
    for _ in range(6):
        res = ctrl.step(q)
        statuses.append(res.diagnostics.status)
        q = q + T * res.qd_command
    assert isinstance(ctrl.qp.inner, DaqpBackend) and ctrl.qp.inner.form == "dense"
    assert [s.startswith("invalid_bounds") for s in statuses] == [0, 0, 1, 1, 0, 0]
    assert ctrl.qp.false_successes == 0


def test_parameters_changed_after_construction_are_used(lbr4p):
    """qd_max (reassigned and in place), q_min/q_max (faults.analysis.position_margin), K,
    λ1, T and the braking switch are read at every step: the QP of the next steps is the one
    written with the new values."""
    lim = lbr4p.limits
    ctrl = make(lbr4p, Circle(2.0))
    q = LBR4P_Q0.copy()
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
        change(ctrl)
        for _ in range(60):
            prev = ctrl.qd_prev.copy()
            res = ctrl.step(q)
            check_step(ctrl, res)
            qp, _ = ctrl.qp.last
            period = ctrl.period_s
            a_max = np.full(7, 10.0)
            brake = braking_constants(a_max, period) if ctrl.braking_aware else None
            lo, hi = _vp_box(q, ctrl.q_min, ctrl.q_max, ctrl.qd_max, period, brake)
            box = intersect_acceleration(lo, hi, prev, period * a_max)
            np.testing.assert_array_equal(qp.lower[:7], box.lower)
            np.testing.assert_array_equal(qp.upper[:7], box.upper)
            x, jac = lbr4p.pose_and_jacobian(q)
            xd, dxd = ctrl.trajectory.target_pair(res.sigma)
            if x @ xd < 0.0:
                x, jac = -x, -jac
            g = np.column_stack([jac, ctrl.gain_per_s * (x - xd) - dxd])
            expected = 2.0 * ctrl.task_weight * g.T @ g
            expected[np.arange(7), np.arange(7)] += 2.0 * ctrl.regularization
            expected[7, 7] += 2.0 * ctrl.scaling_weight
            np.testing.assert_allclose(qp.hessian[0], expected, rtol=1e-12, atol=1e-12)
            q = q + period * res.qd_command


def test_result_objects_without_the_fast_fill(lbr4p):
    """Where the dataclasses would not be built by filling ``__dict__``, their own
    constructors; either way the objects are equal."""
    new, ref = make(lbr4p, Circle(2.0)), make(lbr4p, Circle(2.0))
    assert new._new_result is not StepResult  # the fast fill applies to these dataclasses
    ref._new_diag, ref._new_result = StepDiagnostics, StepResult
    q = LBR4P_Q0.copy()
    new.reset(q)
    ref.reset(q)
    ignore = {"step_time_s", "solve_time_s", "levels_time_s"}
    for _ in range(20):
        r_new, r_ref = new.step(q), ref.step(q)
        d_new = {k: v for k, v in vars(r_new.diagnostics).items() if k not in ignore}
        d_ref = {k: v for k, v in vars(r_ref.diagnostics).items() if k not in ignore}
        assert d_new == d_ref
        for key in ("qd_command", "pose", "target"):
            np.testing.assert_array_equal(getattr(r_new, key), getattr(r_ref, key))
        assert (r_new.s, r_new.sigma, r_new.sigma_next) == (r_ref.s, r_ref.sigma, r_ref.sigma_next)
        q = q + T * r_new.qd_command
    assert vars(r_new).keys() == vars(r_ref).keys()
    assert (
        dataclasses.replace(r_new, diagnostics=r_ref.diagnostics).diagnostics is r_ref.diagnostics
    )


# ------------------------------------------------------------------ the box, bit for bit


def random_state(rng, n, q_min, q_max, qd_max, a_max, period, braking):
    """Positions inside, near and beyond the limits and right at the proportional clip's
    ``far`` distance; previous commands up to 1.5 qd_max (acceleration conflicts)."""
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
    """12 controllers × 250 seeded states: the bounds the backend receives, those of
    ``last_problem()``, and the conflict joints are ``_vp_box`` + ``intersect_acceleration``
    exactly (3000 states in all)."""
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
    ctrl.reset(LBR4P_Q0)
    brake = braking_constants(a_max, period) if braking else None
    for _ in range(250):
        q, qd_prev = random_state(rng, n, ctrl.q_min, ctrl.q_max, qd_max, a_max, period, braking)
        ctrl.qd_prev = qd_prev
        res = ctrl.step(q)
        lo, hi = _vp_box(q, ctrl.q_min, ctrl.q_max, qd_max, period, brake)
        box = intersect_acceleration(lo, hi, qd_prev, period * a_max)
        qp, _ = ctrl.qp.last
        prob = ctrl.last_problem()
        for lower, upper in ((qp.lower, qp.upper), (prob.lower, prob.upper)):
            np.testing.assert_array_equal(lower[:n], box.lower)
            np.testing.assert_array_equal(upper[:n], box.upper)
        assert res.diagnostics.conflict_joints == tuple(np.flatnonzero(box.conflict).tolist())
        if not res.diagnostics.fallback:
            np.testing.assert_array_equal(res.qd_command, box.project(res.qd_command))
