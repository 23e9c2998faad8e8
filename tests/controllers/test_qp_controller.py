"""The QP controller's pipeline (dqcontrol/controllers/qp_controller.py) on compositions
built directly from a prediction, terms and limits: the applied command and scaling against
an independent solve of the posed problem (quadprog), the plan it remembers, the remedy that
drops the relaxable limits, the safe fallback, and its errors; and random compositions of
limits (hypothesis) that never give a command outside any limit."""

from __future__ import annotations

import numpy as np
import pytest
import quadprog
from hypothesis import given, settings
from hypothesis import strategies as st
from joint_below_limit import KeepJointBelow

from dqcontrol.controllers import PredictiveController
from dqcontrol.controllers.core.problem import Bounds, DecisionLayout, Inequality, Level
from dqcontrol.controllers.limits.acceleration import AccelerationLimit
from dqcontrol.controllers.limits.joint_box import JointBoxLimit
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.limits.scaling_range import ScalingRange
from dqcontrol.controllers.limits.velocity import VelocityLimit
from dqcontrol.controllers.prediction import ThesisPrediction, prediction_instants
from dqcontrol.controllers.qp_controller import QPController
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.controllers.terms.scaling import ScalingTerm
from dqcontrol.controllers.terms.tracking import TrackingTerm
from dqcontrol.errors import ParameterError
from dqcontrol.faults.qp_faults import ContradictoryBoundsQP
from dqcontrol.model import LBR4P_Q0
from dqcontrol.trajectories import Circle

T = 0.05
#: The thesis's controller velocity bound (eq. 4.13) and constant acceleration bound.
THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
THESIS_ACC = 10.0


def compose(robot, p: int, *, predicted_box: bool = False, **kw) -> QPController:
    """The thesis's cost and bounds as a plain composition over ``p`` blocks."""
    tau = prediction_instants(p, 0.5) if p > 1 else np.zeros(1)
    durations = np.append(np.diff(tau), np.diff(tau)[-1:]) if p > 1 else np.array([T])
    layout = DecisionLayout(robot.nq, tau, durations)
    lim = robot.limits
    q_min, q_max = lim.q_min + 5e-3, lim.q_max - 5e-3
    limits = [
        JointBoxLimit(layout, q_min, q_max, THESIS_VEL),
        AccelerationLimit(layout, T, np.diff(tau)),
    ]
    if predicted_box:
        limits.append(JointBoxLimit(layout, q_min, q_max, THESIS_VEL, predicted=True))
    limits.append(ScalingRange(layout, 0.0, 1.0))
    terms = (TrackingTerm(10.0), ScalingTerm(layout, 1e-3), DampingTerm(layout, 1e-6))
    return QPController(
        robot, Circle(1.0), T, prediction=ThesisPrediction(layout, T), levels=(Level(terms),),
        limits=tuple(limits), acceleration_limit=THESIS_ACC, **kw,
    )  # fmt: skip


def reference_qp(problem) -> np.ndarray:
    """Independent dense active-set solution (quadprog) of the first level's QP."""
    p_mat = problem.P + 1e-13 * np.eye(problem.c.size)
    lo, up, a = problem.lower, problem.upper, problem.A
    fl, fu = np.isfinite(lo), np.isfinite(up)
    eq = fl & fu & (lo == up)
    rows = [a[eq], a[fl & ~eq], -a[fu & ~eq]]
    rhs = [lo[eq], lo[fl & ~eq], -up[fu & ~eq]]
    c_mat, b_vec = np.vstack(rows).T, np.concatenate(rhs)
    return quadprog.solve_qp(p_mat, -problem.c, c_mat, b_vec, int(eq.sum()))[0]


@pytest.mark.parametrize("p", [1, 4])
def test_the_applied_command_is_the_solution_of_the_posed_problem(lbr4p, p):
    ctrl = compose(lbr4p, p)
    n = lbr4p.nq
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    for _ in range(6):
        sigma = ctrl.sigma
        res = ctrl.step(q)
        x = reference_qp(ctrl.last_problem())
        assert not res.diagnostics.fallback and res.diagnostics.status == "solved"
        np.testing.assert_allclose(res.qd_command, x[:n], atol=2e-5)
        assert res.s == pytest.approx(min(max(x[n], 0.0), 1.0), abs=2e-6)
        assert res.sigma == sigma and res.sigma_next == sigma + T * res.s
        assert ctrl.sigma == res.sigma_next and ctrl.qd_prev is res.qd_command
        # the reported pose is the measured one, sign-aligned to the target
        x_now = lbr4p.pose(q)
        np.testing.assert_allclose(
            res.pose, np.copysign(1.0, x_now @ res.target) * x_now, atol=1e-12
        )
        if p == 1:
            assert res.horizon_qd is None and res.horizon_s is None
        else:  # the plan is remembered: its first block the applied command
            np.testing.assert_array_equal(res.horizon_qd[0], res.qd_command)
            np.testing.assert_array_equal(ctrl.prediction_model.horizon_qd, res.horizon_qd)
            np.testing.assert_array_equal(ctrl.prediction_model.horizon_s, res.horizon_s)
        q = q + T * res.qd_command


def test_the_remedy_drops_the_relaxable_limits_only(lbr4p):
    plain, relaxable = compose(lbr4p, 4), compose(lbr4p, 4, predicted_box=True)
    assert plain._remedies() == ()
    (remedy,) = relaxable._remedies()
    assert remedy.name == "dropped"
    assert remedy.limits == tuple(lim for lim in relaxable.limits if not lim.relaxable)
    assert len(remedy.limits) == len(relaxable.limits) - 1
    # joint 1 at full speed 50 mrad before its bound: the predicted boxes cannot all hold
    q = LBR4P_Q0.copy()
    q[0] = lbr4p.limits.q_max[0] - 0.05
    qd0 = np.zeros(7)
    qd0[0] = THESIS_VEL[0]
    relaxable.reset(q, qd0)
    res = relaxable.step(q)
    assert res.diagnostics.relaxed and not res.diagnostics.fallback
    assert res.diagnostics.message == "predicted position bounds dropped to regain feasibility"
    assert "joint_box_predicted" not in {b.name for b in relaxable.last_problem().bounds}
    relaxable.reset(LBR4P_Q0)  # far from the bounds: the problem as first posed
    assert not relaxable.step(LBR4P_Q0).diagnostics.relaxed
    assert "joint_box_predicted" in {b.name for b in relaxable.last_problem().bounds}
    assert res.diagnostics.conflict_joints == (0,)


def test_a_composition_needs_a_level_and_a_step_before_its_problem(lbr4p):
    layout = DecisionLayout(lbr4p.nq, np.zeros(1), np.array([T]))
    with pytest.raises(ParameterError, match="at least one priority level"):
        QPController(lbr4p, Circle(1.0), T, prediction=ThesisPrediction(layout, T), levels=())
    ctrl = compose(lbr4p, 1)
    with pytest.raises(ParameterError, match=r"no QP has been built yet: call step\(\) first"):
        ctrl.last_problem()
    assert ctrl.qp is ctrl.backend
    replacement = compose(lbr4p, 1).backend
    ctrl.qp = replacement
    assert ctrl.backend is replacement


@pytest.mark.parametrize(
    "solver,settings", [("osqp", {"max_iter": 1, "hot_start": False}), ("daqp", {"iter_limit": 1})]
)
def test_failed_qp_falls_back_safely(lbr4p, solver, settings):
    ctrl = PredictiveController(
        lbr4p, Circle(1.0), T, num_instants=6, velocity_limits=THESIS_VEL,
        acceleration_limit=THESIS_ACC, solver=solver, solver_settings=settings,
    )  # fmt: skip
    q = LBR4P_Q0.copy()
    ctrl.reset(q, qd0=np.full(7, 0.5))
    res = ctrl.step(q)
    assert res.diagnostics.fallback and res.s == 0.0
    assert "fallback" in res.diagnostics.message
    # decelerates towards zero within the acceleration bound
    np.testing.assert_allclose(res.qd_command, np.full(7, 0.5 - T * THESIS_ACC))


# Random compositions of limits (hypothesis, seeded): never a command outside any limit,
# and the fallback admissible (docs/theory.md §5, §7). The soft limits drawn are consistent
# with each other on every state reached (each admits a command there, the joint box's
# beyond-a-limit rule included): the core resolves a conflict between a hard and a soft
# bound, not two contradictory soft ones.

T_COMPOSED = 0.02
N_COMPOSED = 7


class SumOfSpeeds(Limit):
    """General rows: ``|Σ_j qd_i,j| ≤ bound`` at every block."""

    name = "sum_of_speeds"

    def __init__(self, bound: float) -> None:
        self.bound = bound

    def rows(self, ctx) -> Inequality:
        layout = ctx.layout
        c = np.zeros((layout.num_blocks, layout.num_vars))
        for i, idx in enumerate(layout.qd_index()):
            c[i, idx] = 1.0
        up = np.full(layout.num_blocks, self.bound)
        return Inequality(self.name, c, -up, up)


def compose_random(robot, p, choice, rng, q):
    """A controller with the limits ``choice`` picks (each limit with random settings; the
    angle to keep a joint below is above its start ``q``)."""
    tau = prediction_instants(p, 0.5) if p > 1 else np.zeros(1)
    durations = np.append(np.diff(tau), np.diff(tau)[-1:]) if p > 1 else np.array([T_COMPOSED])
    layout = DecisionLayout(N_COMPOSED, tau, durations)
    lim = robot.limits
    q_min, q_max = lim.q_min + 5e-3, lim.q_max - 5e-3
    qd_max = rng.uniform(0.5, 3.0, N_COMPOSED)
    pool = [
        JointBoxLimit(layout, q_min, q_max, qd_max, bool(rng.random() < 0.7)),
        JointBoxLimit(layout, q_min, q_max, qd_max, True, predicted=True),
        AccelerationLimit(layout, T_COMPOSED, np.diff(tau)),
        ScalingRange(layout, 0.0, 1.0),
        VelocityLimit(layout, rng.uniform(0.3, 2.0, N_COMPOSED)),
        KeepJointBelow(j := int(rng.integers(N_COMPOSED)), float(q[j] + rng.uniform(0.0, 0.3))),
        SumOfSpeeds(float(rng.uniform(0.5, 4.0))),
    ]
    limits = tuple(limit for limit, keep in zip(pool, choice, strict=True) if keep)
    terms = (TrackingTerm(10.0), ScalingTerm(layout, 1e-3), DampingTerm(layout, 1e-6))
    ctrl = QPController(
        robot, Circle(1.0), T_COMPOSED, prediction=ThesisPrediction(layout, T_COMPOSED),
        levels=(Level(terms),), limits=limits,
        acceleration_limit=rng.uniform(2.0, 30.0, N_COMPOSED),
    )  # fmt: skip
    return ctrl, limits


def check_command(ctrl, limits, res, prev) -> None:
    """The applied command is inside the merged box of the applied block, and inside every
    limit's own bounds where no hard bound won a conflict."""
    problem = ctrl.last_problem()
    n = N_COMPOSED
    qd = res.qd_command
    assert np.all(qd >= problem.lower[:n]) and np.all(qd <= problem.upper[:n])
    clash = problem.conflict[:n]
    for b in problem.bounds:
        on_applied = b.index < n
        index, lo, up = b.index[on_applied], b.lower[on_applied], b.upper[on_applied]
        if b.hard:
            assert np.all(qd[index] >= lo - 1e-12) and np.all(qd[index] <= up + 1e-12), b.name
        else:
            free = ~clash[index]
            assert np.all(qd[index][free] >= lo[free]), b.name
            assert np.all(qd[index][free] <= up[free]), b.name
    if any(isinstance(limit, AccelerationLimit) for limit in limits):
        step = ctrl.period_s * ctrl._a_batch[0]
        assert np.all(np.abs(qd - prev) <= step * (1 + 1e-12) + 1e-15)
    if not res.diagnostics.fallback:
        assert 0.0 <= res.s <= 1.0


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    p=st.sampled_from([1, 4]),
    choice=st.lists(st.booleans(), min_size=7, max_size=7),
    near=st.booleans(),
    fail=st.booleans(),
)
def test_random_compositions_keep_every_limit(lbr4p, seed, p, choice, near, fail):
    rng = np.random.default_rng(seed)
    lim = lbr4p.limits
    q = rng.uniform(lim.q_min + 0.05, lim.q_max - 0.05)
    if near:
        j = rng.integers(0, N_COMPOSED, 3)
        side = rng.choice([-1.0, 1.0], 3)
        q[j] = np.where(side > 0, lim.q_max[j], lim.q_min[j]) - side * rng.uniform(0, 0.02, 3)
    ctrl, limits = compose_random(lbr4p, p, choice, rng, q)
    qd0 = rng.uniform(-1.0, 1.0, N_COMPOSED)
    ctrl.reset(q, qd0)
    if fail:  # every QP made contradictory: the fallback must be admissible
        ctrl.qp = ContradictoryBoundsQP(ctrl.qp, N_COMPOSED, p, "crossed")
        ctrl.qp.active = True
    for _ in range(4):
        prev = ctrl.qd_prev.copy()
        res = ctrl.step(q)
        if fail:
            assert res.diagnostics.fallback and res.s == 0.0
            problem = ctrl.last_problem()
            safe = np.minimum(
                np.maximum(0.0, problem.lower[:N_COMPOSED]), problem.upper[:N_COMPOSED]
            )
            np.testing.assert_array_equal(res.qd_command, safe)
        check_command(ctrl, limits, res, prev)
        q = q + T_COMPOSED * res.qd_command


def test_a_hard_bound_wins_only_where_it_conflicts(lbr4p):
    """A soft bound the acceleration bound cannot reach: the joint brakes as hard as allowed
    (and is reported), every other joint keeps the soft bound."""
    rng = np.random.default_rng(3)
    q = lbr4p.limits.q_max - 0.01
    ctrl, limits = compose_random(lbr4p, 1, [True, False, True, True, False, False, False], rng, q)
    qd0 = np.full(N_COMPOSED, 0.0)
    qd0[2] = 3.0  # towards the limit, far too fast
    ctrl.reset(q, qd0)
    res = ctrl.step(q)
    assert 2 in res.diagnostics.conflict_joints
    step = T_COMPOSED * ctrl._a_batch[0, 2]
    assert res.qd_command[2] == 3.0 - step
    check_command(ctrl, limits, res, qd0)
    assert isinstance(ctrl.last_problem().bounds[0], Bounds)
