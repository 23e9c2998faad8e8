"""What a controller hands its backend (:mod:`dqcontrol.controllers.core.step_problem`): the
block form and the problem of every level hold the same numbers as ``build_problem``'s,
and the conflict joints are those where the merged hard bound won."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.step_contexts import random_context

from dqcontrol.controllers.core.block_assembly import BlockAssembly
from dqcontrol.controllers.core.levels import build_problem
from dqcontrol.controllers.core.problem import Level
from dqcontrol.controllers.core.step_problem import StepProblem
from dqcontrol.controllers.limits.acceleration import AccelerationLimit
from dqcontrol.controllers.limits.joint_box import JointBoxLimit
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.controllers.terms.scaling import ScalingTerm
from dqcontrol.controllers.terms.tracking import TrackingTerm


def _setup(robot, seed: int):
    """A one-block context with some joints near or beyond a limit and a fast last command
    (so that the acceleration bound, the hard one, wins some conflicts)."""
    ctx = random_context(robot, 1, seed)
    rng = np.random.default_rng(seed)
    lim, layout = robot.limits, ctx.layout
    j = rng.integers(0, robot.nq, 3)
    ctx.q[j] = np.where(rng.random(3) < 0.5, lim.q_max[j], lim.q_min[j])
    ctx.qd_prev = rng.uniform(-3.0, 3.0, robot.nq)
    limits = (
        JointBoxLimit(layout, lim.q_min + 5e-3, lim.q_max - 5e-3, np.full(robot.nq, 2.0), True),
        AccelerationLimit(layout, ctx.period_s, np.diff(layout.instants_s)),
    )
    terms = (TrackingTerm(9.0, 1.5), ScalingTerm(layout, 1e-3), DampingTerm(layout, 1e-6))
    return ctx, terms, limits


def _check_conflicts(step, reference, n):
    want = tuple(np.flatnonzero(reference.conflict[:n]).tolist())
    assert step.conflict_joints(n) == want
    assert step.has_conflict == bool(want)
    return bool(want)


def test_the_block_form_and_the_problem_hold_the_same_numbers(lbr4p):
    conflicts = 0
    for seed in range(8):
        ctx, terms, limits = _setup(lbr4p, seed)
        n = ctx.layout.num_joints
        step = StepProblem(ctx, (Level(terms),), limits, BlockAssembly(terms, limits))
        assert step.block_diagonal and step.block_form is not None
        reference = build_problem(ctx, (Level(terms),), limits)
        np.testing.assert_array_equal(step.lower, reference.lower)
        np.testing.assert_array_equal(step.upper, reference.upper)
        conflicts += _check_conflicts(step, reference, n)
        dense, ref = step.block_form.dense(), reference.dense(0)
        np.testing.assert_allclose(dense.P, ref.P, rtol=0, atol=1e-13 * np.abs(ref.P).max())
        problem = step.problem()
        assert step.problem() is problem  # built once
        np.testing.assert_array_equal(problem.lower, reference.lower)
        np.testing.assert_allclose(problem.P, ref.P, rtol=1e-13, atol=1e-15)
    assert conflicts > 0, "a hard bound won somewhere"


@pytest.mark.parametrize("levels", [1, 2])
def test_without_an_assembly_the_bounds_come_from_the_problem(lbr4p, levels):
    conflicts = 0
    for seed in range(8):
        ctx, terms, limits = _setup(lbr4p, 20 + seed)
        n = ctx.layout.num_joints
        level_list = (Level(terms[:1]), Level(terms[1:])) if levels == 2 else (Level(terms),)
        step = StepProblem(ctx, level_list, limits)
        assert step.block_form is None and not step.block_diagonal
        assert step.lower is None and step.upper is None
        reference = build_problem(ctx, level_list, limits)
        conflicts += _check_conflicts(step, reference, n)  # builds the problem when asked
        np.testing.assert_array_equal(step.lower, reference.lower)
        np.testing.assert_array_equal(step.upper, reference.upper)
        assert len(step.problem().levels) == levels
    assert conflicts > 0, "a hard bound won somewhere"
