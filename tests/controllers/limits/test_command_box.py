"""The applied block's command box as one limit (docs/theory.md §5): its rows are the joint
box's and the acceleration bound's, and its one-pass fast path merges exactly what the two
limits give merged apart, conflicts included; and ``command_box`` where the position and
acceleration bounds conflict: the acceleration bound kept, the joint braking."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.limits.test_joint_box import near_limits, numpy_box, numpy_conflict_rule
from controllers.terms.step_contexts import random_context

from dqcontrol.controllers import command_box
from dqcontrol.controllers.core.block_assembly import BlockAssembly
from dqcontrol.controllers.core.levels import build_problem
from dqcontrol.controllers.core.problem import Level
from dqcontrol.controllers.limits.acceleration import AccelerationLimit
from dqcontrol.controllers.limits.command_box import CommandBoxLimit
from dqcontrol.controllers.limits.joint_box import JointBoxLimit
from dqcontrol.controllers.limits.scaling_range import ScalingRange
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.errors import ParameterError


def pieces(ctx, braking: bool):
    lim = ctx.robot.limits
    layout = ctx.layout
    q_min, q_max = lim.q_min + 5e-3, lim.q_max - 5e-3
    qd_max = np.linspace(1.0, 3.0, layout.num_joints)
    box = JointBoxLimit(layout, q_min, q_max, qd_max, braking)
    accel = AccelerationLimit(layout, ctx.period_s, np.diff(layout.instants_s))
    return box, accel


@pytest.mark.parametrize("p", [1, 4])
@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("braking", [True, False])
def test_command_box_equals_its_two_limits(lbr4p, p, seed, braking):
    ctx = random_context(lbr4p, p, seed=seed)
    near_limits(ctx, seed)
    rng = np.random.default_rng(seed)
    ctx.qd_prev = rng.uniform(-5.0, 5.0, lbr4p.nq)  # conflicts with the box happen
    box, accel = pieces(ctx, braking)
    layout, n = ctx.layout, lbr4p.nq
    command = CommandBoxLimit(box, accel)
    rows = command.rows(ctx)
    assert [item.name for item in rows[:2]] == ["joint_box", "acceleration_first"]
    assert not rows[0].hard and rows[1].hard and len(rows) == (3 if p > 1 else 2)
    # the numpy reference: the box at q, then the acceleration bound (conflict rule)
    lo, hi = numpy_box(ctx.q, box.q_min, box.q_max, box.qd_max, ctx.period_s,
                       ctx.a_max[0] if braking else None)  # fmt: skip
    step = ctx.period_s * ctx.a_max[0]
    lo, hi, clash = numpy_conflict_rule(lo, hi, ctx.qd_prev - step, ctx.qd_prev + step)
    # the fast path (the assembly) against the rows (build_problem) and the two limits
    scaling = ScalingRange(layout, 0.0, 1.0)
    terms = (DampingTerm(layout, 1.0),)
    assembly = BlockAssembly(terms, (command, scaling))
    qp = assembly.build(ctx)
    problem = build_problem(ctx, (Level(terms),), (command, scaling))
    apart = build_problem(ctx, (Level(terms),), (box, scaling, accel))
    for lower, upper in ((qp.lower, qp.upper), (problem.lower, problem.upper)):
        np.testing.assert_array_equal(lower, apart.lower)
        np.testing.assert_array_equal(upper, apart.upper)
    np.testing.assert_allclose(qp.lower[:n], lo, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(qp.upper[:n], hi, rtol=1e-14, atol=1e-14)
    np.testing.assert_array_equal(assembly.conflict[:n].astype(bool), apart.conflict[:n])
    np.testing.assert_array_equal(apart.conflict[:n], clash)
    assert assembly.has_conflict == bool(clash.any())
    np.testing.assert_array_equal(qp.C, apart.C)


def test_a_predicted_box_is_refused(lbr4p):
    ctx = random_context(lbr4p, 3, seed=1)
    box, _ = pieces(ctx, True)
    other = JointBoxLimit(ctx.layout, box.q_min, box.q_max, box.qd_max, True, predicted=True)
    with pytest.raises(ParameterError, match="applied block"):
        CommandBoxLimit(other, AccelerationLimit(ctx.layout, 0.01, np.ones(2)))


def test_command_box_conflict_keeps_acceleration_and_brakes():
    q_max = np.array([1.0])
    box = command_box(
        q=np.array([0.99]), qd_prev=np.array([2.0]), q_min=-q_max, q_max=q_max,
        qd_max=np.array([3.0]), a_max=np.array([10.0]), period_s=0.05,
    )  # fmt: skip
    # one period allows at most (1 - 0.99)/T = 0.2 rad/s; the brake reaches only 1.5
    assert box.conflict[0]
    assert box.lower[0] == box.upper[0] == pytest.approx(1.5)
