"""Each limit of the QP core against an independent numpy computation (docs/theory.md §5,
§7.3), the merge of bounds (the conflict rule), and the fast assembly of a level's QP
against the problem as :func:`~dqcontrol.controllers.core.levels.build_problem` writes it."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.test_terms import random_context

from dqcontrol.controllers.core.block_assembly import BlockAssembly
from dqcontrol.controllers.core.levels import build_problem
from dqcontrol.controllers.core.problem import Bounds, Inequality, Level, Residual
from dqcontrol.controllers.limits.acceleration import AccelerationLimit
from dqcontrol.controllers.limits.joint_box import JointBoxLimit
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.limits.scaling_range import ScalingRange
from dqcontrol.controllers.limits.velocity import VelocityLimit
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.controllers.terms.scaling import ScalingTerm
from dqcontrol.controllers.terms.stall_damping import StallDampingTerm
from dqcontrol.controllers.terms.term import Term
from dqcontrol.controllers.terms.tracking import TrackingTerm


def numpy_box(q, q_min, q_max, qd_max, period, a_max):
    """Velocity ∩ position through one period ∩ braking (``a_max`` or None), one side at a
    time; beyond a limit only moving back (docs/theory.md §5)."""
    hi = np.minimum(qd_max, (q_max - q) / period)
    lo = np.maximum(-qd_max, (q_min - q) / period)
    if a_max is not None:
        at = a_max * period

        def brake(d):
            return -at + np.sqrt(at * at + 2.0 * a_max * np.maximum(d, 0.0))

        hi = np.minimum(hi, brake(q_max - q))
        lo = np.maximum(lo, -brake(q - q_min))
    hi = np.maximum(hi, np.minimum(lo, qd_max))
    lo = np.minimum(lo, hi)
    return lo, hi


def numpy_conflict_rule(lo, hi, lo_h, hi_h):
    """``[lo, hi] ∩ [lo_h, hi_h]``, the hard one kept where they do not meet (its point
    closest to the other)."""
    out_lo, out_hi = np.maximum(lo, lo_h), np.minimum(hi, hi_h)
    clash = out_lo > out_hi
    point = np.where(hi_h < lo, hi_h, lo_h)
    return np.where(clash, point, out_lo), np.where(clash, point, out_hi), clash


def limits_of(ctx, braking=True):
    lim = ctx.robot.limits
    layout = ctx.layout
    q_min, q_max = lim.q_min + 5e-3, lim.q_max - 5e-3
    qd_max = np.linspace(1.0, 3.0, layout.num_joints)
    coupling = np.diff(layout.instants_s)
    return (
        JointBoxLimit(layout, q_min, q_max, qd_max, braking),
        JointBoxLimit(layout, q_min, q_max, qd_max, braking, predicted=True),
        ScalingRange(layout, 0.0, 1.0),
        AccelerationLimit(layout, ctx.period_s, coupling),
    )


def near_limits(ctx, seed):
    """Move some joints of the measured and predicted states near or beyond the limits."""
    rng = np.random.default_rng(seed)
    lim = ctx.robot.limits
    for qs in (ctx.q[None, :], ctx.prediction.q_lin):
        for row in qs:
            j = rng.integers(0, row.size, 3)
            row[j] = np.where(rng.random(3) < 0.5, lim.q_max[j], lim.q_min[j])
            row[j] += rng.uniform(-0.03, 0.01, 3) * np.sign(row[j])
    ctx.qd_prev = rng.uniform(-3.0, 3.0, ctx.q.size)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("braking", [True, False])
def test_joint_box_and_acceleration_rows(lbr4p, seed, braking):
    ctx = random_context(lbr4p, 5, seed=seed)
    near_limits(ctx, seed)
    box, box_pred, _, accel = limits_of(ctx, braking)
    layout, n = ctx.layout, lbr4p.nq
    idx = layout.qd_index()
    a = ctx.a_max
    # the applied block at q
    applied = box.rows(ctx)
    lo, hi = numpy_box(ctx.q, box.q_min, box.q_max, box.qd_max, ctx.period_s,
                       a[0] if braking else None)  # fmt: skip
    np.testing.assert_array_equal(applied.index, idx[0])
    np.testing.assert_allclose(applied.lower, lo, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(applied.upper, hi, rtol=1e-14, atol=1e-14)
    # the predicted blocks at the clipped predicted states
    pred = box_pred.rows(ctx)
    q_clip = np.clip(ctx.prediction.q_lin[1:], box.q_min, box.q_max)
    lo_p, hi_p = numpy_box(q_clip, box.q_min, box.q_max, box.qd_max, ctx.period_s,
                           a[1:] if braking else None)  # fmt: skip
    np.testing.assert_array_equal(pred.index, idx[1:].ravel())
    np.testing.assert_allclose(pred.lower, lo_p.ravel(), rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(pred.upper, hi_p.ravel(), rtol=1e-14, atol=1e-14)
    assert box_pred.relaxable and not box.relaxable
    # acceleration: hard bound on qd_0, coupling rows qd_i - qd_(i-1)
    first, coupling = accel.rows(ctx)
    assert first.hard
    np.testing.assert_allclose(first.lower, ctx.qd_prev - ctx.period_s * a[0], atol=1e-15)
    np.testing.assert_allclose(first.upper, ctx.qd_prev + ctx.period_s * a[0], atol=1e-15)
    z = np.random.default_rng(seed).normal(size=layout.num_vars)
    qd = z.reshape(layout.num_blocks, -1)[:, :n]
    np.testing.assert_allclose(coupling.C @ z, np.diff(qd, axis=0).ravel(), atol=1e-15)
    dv = (np.diff(layout.instants_s)[:, None] * a[1:]).ravel()
    np.testing.assert_allclose(coupling.upper, dv, atol=0)
    np.testing.assert_allclose(coupling.lower, -dv, atol=0)


@pytest.mark.parametrize("seed", range(6))
def test_merged_bounds_follow_the_conflict_rule(lbr4p, seed):
    ctx = random_context(lbr4p, 3, seed=seed)
    near_limits(ctx, seed)
    limits = limits_of(ctx)
    problem = build_problem(ctx, (Level((DampingTerm(ctx.layout, 1.0),)),), limits)
    n, a = lbr4p.nq, ctx.a_max
    lo, hi = numpy_box(ctx.q, limits[0].q_min, limits[0].q_max, limits[0].qd_max,
                       ctx.period_s, a[0])  # fmt: skip
    step = ctx.period_s * a[0]
    lo, hi, clash = numpy_conflict_rule(lo, hi, ctx.qd_prev - step, ctx.qd_prev + step)
    np.testing.assert_allclose(problem.lower[:n], lo, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(problem.upper[:n], hi, rtol=1e-14, atol=1e-14)
    np.testing.assert_array_equal(problem.conflict[:n], clash)
    s_idx = ctx.layout.s_index()
    np.testing.assert_array_equal(problem.lower[s_idx], 0.0)
    np.testing.assert_array_equal(problem.upper[s_idx], 1.0)
    assert np.all(problem.lower <= problem.upper)  # never empty


def test_scaling_range_fixed_without_scaling(lbr4p):
    ctx = random_context(lbr4p, 2, seed=1)
    free = ScalingRange(ctx.layout, 0.0, 1.0).rows(ctx)
    fixed = ScalingRange(ctx.layout, 1.0, 1.0).rows(ctx)
    assert not free.fixed and fixed.fixed
    np.testing.assert_array_equal(fixed.index, ctx.layout.s_index())
    problem = build_problem(ctx, (Level((DampingTerm(ctx.layout, 1.0),)),),
                            (ScalingRange(ctx.layout, 1.0, 1.0),))  # fmt: skip
    np.testing.assert_array_equal(np.flatnonzero(problem.fixed), ctx.layout.s_index())


# --------------------------------------------------------------------- the fast assembly


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


def test_compiled_braking_and_coupling_constants_are_numpys():
    """The limits' per-step constants from a moving ``a_max``: the braking rows
    ``[a T; 2 a; (a T)²]`` and the coupling steps ``±h_i a_max[i + 1]``, bit for bit."""
    from dqcontrol.controllers.core.bounds import braking_constants
    from dqcontrol.controllers.core.box_rules import braking_rows
    from dqcontrol.controllers.limits.acceleration import coupling_steps

    rng = np.random.default_rng(31)
    a_max = rng.uniform(0.5, 50.0, size=(6, 7))
    assert np.array_equal(braking_rows(a_max[0], 1e-3), np.array(braking_constants(a_max[0], 1e-3)))
    h = rng.uniform(0.01, 0.2, size=5)
    dv, neg_dv = coupling_steps(h, a_max)
    assert np.array_equal(dv, (h[:, None] * a_max[1:]).ravel())
    assert np.array_equal(neg_dv, -dv)
    steady = np.broadcast_to(a_max[0], (6, 7))  # a constant bound, as the controllers pass it
    assert np.array_equal(coupling_steps(h, steady)[0], (h[:, None] * steady[1:]).ravel())
