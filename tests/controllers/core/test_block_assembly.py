"""The block assembly (:mod:`dqcontrol.controllers.core.block_assembly`): the fast assembly of
a level's QP against the problem as :func:`~dqcontrol.controllers.core.levels.build_problem`
writes it (generic terms and limits mixed in, a term across blocks, a limit that changes its
rows), and its helpers: a residual's blocks and linear term against the dense objective,
bounds merged one by one against ``merge_bounds``, and ``overrides``."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from controllers.limits.test_joint_box import limits_of, near_limits
from controllers.terms.step_contexts import random_context

from dqcontrol.controllers.core.block_assembly import (
    BlockAssembly,
    add_residual,
    merge_into,
    overrides,
)
from dqcontrol.controllers.core.levels import build_problem
from dqcontrol.controllers.core.problem import (
    Bounds,
    DecisionLayout,
    Inequality,
    Level,
    Residual,
    merge_bounds,
)
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.limits.velocity import VelocityLimit
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.controllers.terms.scaling import ScalingTerm
from dqcontrol.controllers.terms.stall_damping import StallDampingTerm
from dqcontrol.controllers.terms.term import Term
from dqcontrol.controllers.terms.tracking import TrackingTerm


class CouplingTerm(Term):
    """A term whose rows touch two blocks: ``qd_1 - qd_0`` (the level is then not block
    diagonal)."""

    name = "coupling"

    def residual(self, ctx):
        layout = ctx.layout
        idx = layout.qd_index()
        a = np.zeros((layout.num_joints, layout.num_vars))
        a[np.arange(layout.num_joints), idx[1]] = 1.0
        a[np.arange(layout.num_joints), idx[0]] = -1.0
        return Residual(self.name, 0.5, np.zeros(layout.num_joints), A=a)


class OffsetTerm(Term):
    """A block term with ``b ≠ 0`` and no fast path: ``qd_i - 0.1``."""

    name = "offset"

    def residual(self, ctx):
        layout = ctx.layout
        p, n, m = layout.num_blocks, layout.num_joints, layout.block_size
        blocks = np.zeros((p, n, m))
        blocks[:, np.arange(n), np.arange(n)] = 1.0
        return Residual(self.name, 0.3, np.full(p * n, 0.1), blocks=blocks)


class SumRow(Limit):
    """A generic limit with a hard bound and a row: ``Σ_j qd_0,j ≤ 1`` and ``|qd_0,0| ≤ 0.2``."""

    name = "sum_row"

    def rows(self, ctx):
        layout = ctx.layout
        c = np.zeros((1, layout.num_vars))
        c[0, layout.qd_index()[0]] = 1.0
        hard = Bounds("sum_row_hard", np.array([0]), np.array([-0.2]), np.array([0.2]), hard=True)
        return Inequality(self.name, c, np.array([-np.inf]), np.array([1.0])), hard


@pytest.mark.parametrize("extra", [False, True])
@pytest.mark.parametrize("p", [1, 5])
def test_block_assembly_equals_the_built_problem(lbr4p, p, extra):
    """The fast paths (compiled Gram blocks, bounds straight into the QP's arrays) give the
    dense QP of ``build_problem`` (to rounding), with generic terms and limits mixed in."""
    ctx = random_context(lbr4p, p, seed=10 + p)
    near_limits(ctx, p)
    layout = ctx.layout
    stall = StallDampingTerm(layout, 1e-3, 0.05, 0)
    stall.observe(None, 0.01)
    terms = (TrackingTerm(9.0, 1.5), ScalingTerm(layout, 1e-3), DampingTerm(layout, 1e-6), stall)
    limits = tuple(lim for lim in limits_of(ctx) if p > 1 or not lim.relaxable)
    limits = limits + (VelocityLimit(layout, np.full(7, 2.0)),)
    if extra:
        terms = terms + (OffsetTerm(),)
        limits = limits + (SumRow(),)
    stall.prepare(ctx)
    assert stall.weight > 0.0
    assembly = BlockAssembly(terms, limits)
    qp = assembly.build(ctx)
    dense = qp.dense()
    problem = build_problem(ctx, (Level(terms),), limits)
    ref = problem.dense(0)
    scale = np.abs(ref.P).max()
    np.testing.assert_allclose(dense.P, ref.P, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(dense.c, ref.c, rtol=0, atol=1e-13 * max(1.0, np.abs(ref.c).max()))
    np.testing.assert_array_equal(dense.A, ref.A)
    np.testing.assert_array_equal(dense.lower, ref.lower)
    np.testing.assert_array_equal(dense.upper, ref.upper)
    assert qp.fixed == tuple(np.flatnonzero(problem.fixed))
    # relaxed: the predicted boxes dropped, nothing else
    if p > 1:
        relaxed = assembly.build(ctx, relaxed=True)
        kept = tuple(lim for lim in limits if not lim.relaxable)
        ref_relaxed = build_problem(ctx, (Level(terms),), kept).dense(0)
        np.testing.assert_array_equal(relaxed.lower, ref_relaxed.lower)
        np.testing.assert_array_equal(relaxed.upper, ref_relaxed.upper)


def test_a_term_across_blocks_is_not_assembled_by_blocks(lbr4p):
    ctx = random_context(lbr4p, 3, seed=4)
    assert BlockAssembly((CouplingTerm(),), limits_of(ctx)).build(ctx) is None


def test_a_limit_that_changes_its_rows_starts_a_new_structure(lbr4p):
    ctx = random_context(lbr4p, 2, seed=6)

    class Sometimes(Limit):
        name = "sometimes"
        active = False

        def rows(self, ctx):
            if not self.active:
                return None
            c = np.zeros((2, ctx.layout.num_vars))
            c[0, 0] = c[1, 1] = 1.0
            return Inequality(self.name, c, -np.ones(2), np.ones(2))

    sometimes = Sometimes()
    assembly = BlockAssembly((DampingTerm(ctx.layout, 1.0),), limits_of(ctx) + (sometimes,))
    first = assembly.build(ctx)
    sometimes.active = True
    second = assembly.build(ctx)
    assert second.structure != first.structure
    assert second.C.shape[0] == first.C.shape[0] + 2
    np.testing.assert_array_equal(second.upper[-2:], 1.0)
    sometimes.active = False
    third = assembly.build(ctx)
    assert third.C.shape == first.C.shape and third.structure not in (first.structure,
                                                                      second.structure)  # fmt: skip


@pytest.mark.parametrize("weighted", [False, True])
def test_add_residual_adds_the_blocks_of_the_weighted_sum_of_squares(weighted):
    """``2 w Aᵀ W A`` block by block and ``-2 w Aᵀ W b``, with ``A`` the blocks' block
    diagonal and ``W`` the row weights (1 without)."""
    rng = np.random.default_rng(1 + weighted)
    blocks = rng.normal(size=(3, 5, 4))
    row_weights = rng.uniform(0.5, 2.0, 15) if weighted else None
    res = Residual("r", 0.8, rng.normal(size=15), blocks=blocks, row_weights=row_weights)
    hessian, c = np.full((3, 4, 4), 0.25), np.ones(12)
    add_residual(hessian, c, res)
    a = scipy.linalg.block_diag(*blocks)
    a_w = a * (np.ones(15) if row_weights is None else row_weights)[:, None]
    p_ref, c_ref = 2.0 * 0.8 * a_w.T @ a, -2.0 * 0.8 * a_w.T @ res.b
    np.testing.assert_allclose(scipy.linalg.block_diag(*(hessian - 0.25)), p_ref, atol=1e-12)
    np.testing.assert_allclose(c - 1.0, c_ref, atol=1e-12)


def test_bounds_merged_one_by_one_are_merge_bounds():
    rng = np.random.default_rng(3)
    layout = DecisionLayout(4, np.array([0.0, 0.1]), np.full(2, 0.1))
    nv = layout.num_vars
    bounds = []
    for k in range(5):
        index = rng.choice(nv, size=4, replace=False)
        lower = rng.uniform(-2.0, 0.5, 4)
        upper = lower + rng.uniform(0.0, 1.5, 4)
        bounds.append(Bounds(f"b{k}", index, lower, upper, hard=k == 4))  # the hard one last
    lower, upper = np.full(nv, -np.inf), np.full(nv, np.inf)
    conflict = np.zeros(nv, dtype=np.int8)
    for b in bounds:
        merge_into(lower, upper, conflict, b)
    want = merge_bounds(layout, tuple(bounds))
    np.testing.assert_array_equal(lower, want[0])
    np.testing.assert_array_equal(upper, want[1])
    np.testing.assert_array_equal(conflict.view(np.bool_), want[2])


def test_overrides_tells_a_method_of_its_own_from_an_inherited_one():
    class Base:
        def rows(self):
            return None

        def prepare(self):
            return None

    class Child(Base):
        def rows(self):
            return 1

    assert overrides(Child(), Base, "rows")
    assert not overrides(Child(), Base, "prepare")
    assert not overrides(Base(), Base, "rows")
