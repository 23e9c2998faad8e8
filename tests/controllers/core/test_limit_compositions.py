"""Property (hypothesis, seeded): random compositions of limits on random states never give
a command outside any limit, and the fallback is admissible (docs/theory.md §5, §7).

The soft limits drawn here are consistent with each other on every state the test reaches
(each admits a command at the state, the joint box's beyond-a-limit rule included): the
core resolves a conflict between a hard and a soft bound, not two contradictory soft ones
(a QP with such bounds is refused and the step falls back)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from joint_below_limit import KeepJointBelow

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
from dqcontrol.faults.qp_faults import ContradictoryBoundsQP
from dqcontrol.trajectories import Circle

T = 0.02
N = 7


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


def compose(robot, p, choice, rng, q):
    """A controller with the limits ``choice`` picks (each limit with random settings; the
    angle to keep a joint below is above its start ``q``)."""
    tau = prediction_instants(p, 0.5) if p > 1 else np.zeros(1)
    durations = np.append(np.diff(tau), np.diff(tau)[-1:]) if p > 1 else np.array([T])
    layout = DecisionLayout(N, tau, durations)
    lim = robot.limits
    q_min, q_max = lim.q_min + 5e-3, lim.q_max - 5e-3
    qd_max = rng.uniform(0.5, 3.0, N)
    pool = [
        JointBoxLimit(layout, q_min, q_max, qd_max, bool(rng.random() < 0.7)),
        JointBoxLimit(layout, q_min, q_max, qd_max, True, predicted=True),
        AccelerationLimit(layout, T, np.diff(tau)),
        ScalingRange(layout, 0.0, 1.0),
        VelocityLimit(layout, rng.uniform(0.3, 2.0, N)),
        KeepJointBelow(j := int(rng.integers(N)), float(q[j] + rng.uniform(0.0, 0.3))),
        SumOfSpeeds(float(rng.uniform(0.5, 4.0))),
    ]
    limits = tuple(limit for limit, keep in zip(pool, choice, strict=True) if keep)
    terms = (TrackingTerm(10.0), ScalingTerm(layout, 1e-3), DampingTerm(layout, 1e-6))
    ctrl = QPController(
        robot, Circle(1.0), T, prediction=ThesisPrediction(layout, T), levels=(Level(terms),),
        limits=limits, acceleration_limit=rng.uniform(2.0, 30.0, N),
    )  # fmt: skip
    return ctrl, limits


def check_command(ctrl, limits, res, prev) -> None:
    """The applied command is inside the merged box of the applied block, and inside every
    limit's own bounds where no hard bound won a conflict."""
    problem = ctrl.last_problem()
    n = N
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
        j = rng.integers(0, N, 3)
        side = rng.choice([-1.0, 1.0], 3)
        q[j] = np.where(side > 0, lim.q_max[j], lim.q_min[j]) - side * rng.uniform(0, 0.02, 3)
    ctrl, limits = compose(lbr4p, p, choice, rng, q)
    qd0 = rng.uniform(-1.0, 1.0, N)
    ctrl.reset(q, qd0)
    if fail:  # every QP made contradictory: the fallback must be admissible
        ctrl.qp = ContradictoryBoundsQP(ctrl.qp, N, p, "crossed")
        ctrl.qp.active = True
    for _ in range(4):
        prev = ctrl.qd_prev.copy()
        res = ctrl.step(q)
        if fail:
            assert res.diagnostics.fallback and res.s == 0.0
            problem = ctrl.last_problem()
            safe = np.minimum(np.maximum(0.0, problem.lower[:N]), problem.upper[:N])
            np.testing.assert_array_equal(res.qd_command, safe)
        check_command(ctrl, limits, res, prev)
        q = q + T * res.qd_command


def test_a_hard_bound_wins_only_where_it_conflicts(lbr4p):
    """A soft bound the acceleration bound cannot reach: the joint brakes as hard as allowed
    (and is reported), every other joint keeps the soft bound."""
    rng = np.random.default_rng(3)
    q = lbr4p.limits.q_max - 0.01
    ctrl, limits = compose(lbr4p, 1, [True, False, True, True, False, False, False], rng, q)
    qd0 = np.full(N, 0.0)
    qd0[2] = 3.0  # towards the limit, far too fast
    ctrl.reset(q, qd0)
    res = ctrl.step(q)
    assert 2 in res.diagnostics.conflict_joints
    step = T * ctrl._a_batch[0, 2]
    assert res.qd_command[2] == 3.0 - step
    check_command(ctrl, limits, res, qd0)
    assert isinstance(ctrl.last_problem().bounds[0], Bounds)
