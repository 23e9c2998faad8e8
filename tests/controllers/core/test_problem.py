"""The problem's values (:mod:`dqcontrol.controllers.core.problem`): the decision layout's
indices, residual rows and the objective against numpy, the merged bounds against a hand
computation of the conflict rule and against numpy (over the limits of random step contexts,
and of scalars, lists and arrays), the mark of constancy, and the errors on bad input."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from controllers.limits.test_joint_box import (
    limits_of,
    near_limits,
    numpy_box,
    numpy_conflict_rule,
)
from controllers.terms.step_contexts import random_context

from dqcontrol.controllers.core.levels import build_problem
from dqcontrol.controllers.core.problem import (
    BlockQP,
    Bounds,
    BuiltLevel,
    DecisionLayout,
    Inequality,
    Level,
    Problem,
    Residual,
    constant_rows,
    fixed_variables,
    merge_bounds,
    objective,
)
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.errors import ParameterError


def _layout(with_scaling: bool = True) -> DecisionLayout:
    return DecisionLayout(3, np.array([0.0, 0.1, 0.3]), np.array([0.1, 0.2, 0.2]), with_scaling)


def test_the_layout_places_each_block_after_the_last():
    layout = _layout()
    assert (layout.num_blocks, layout.block_size, layout.num_vars) == (3, 4, 12)
    np.testing.assert_array_equal(layout.qd_index(), [[0, 1, 2], [4, 5, 6], [8, 9, 10]])
    np.testing.assert_array_equal(layout.s_index(), [3, 7, 11])
    qd, s = layout.split(np.arange(12.0))
    np.testing.assert_array_equal(qd, [[0, 1, 2], [4, 5, 6], [8, 9, 10]])
    np.testing.assert_array_equal(s, [3, 7, 11])
    plain = _layout(with_scaling=False)
    assert (plain.block_size, plain.num_vars) == (3, 9)
    np.testing.assert_array_equal(plain.qd_index().ravel(), np.arange(9))
    assert plain.split(np.zeros(9))[1] is None
    with pytest.raises(ParameterError, match="no time scaling"):
        plain.s_index()


@pytest.mark.parametrize(
    ("joints", "instants", "durations", "match"),
    [
        (3, [0.1, 0.2], [0.1, 0.1], "instants_s must start at 0"),
        (3, [0.0, 0.2, 0.2], [0.1, 0.1, 0.1], "instants_s must start at 0 and increase"),
        (3, [0.0, 0.2], [0.1], "durations_s must be 2 values > 0"),
        (3, [0.0, 0.2], [0.1, 0.0], "durations_s must be 2 values > 0"),
        (0, [0.0], [0.1], "num_joints must be ≥ 1"),
    ],
)
def test_a_bad_layout_is_refused(joints, instants, durations, match):
    with pytest.raises(ParameterError, match=match):
        DecisionLayout(joints, np.array(instants), np.array(durations))


def test_rows_given_by_blocks_are_block_diagonal():
    rng = np.random.default_rng(1)
    layout = _layout()
    blocks = rng.normal(size=(3, 2, 4))
    res = Residual("blocks", 1.0, rng.normal(size=6), blocks=blocks)
    a = res.dense(layout)
    np.testing.assert_array_equal(a, scipy.linalg.block_diag(*blocks))
    z = rng.normal(size=12)
    np.testing.assert_allclose(res.value(layout, z), a @ z - res.b, rtol=1e-14)


@pytest.mark.parametrize("read_only", [False, True])
def test_the_objective_is_the_weighted_sum_of_squares(read_only):
    """``½ zᵀ P z + cᵀ z = Σ w ‖A z - b‖²`` up to a constant, per-row weights included;
    read-only rows give the same numbers (and a read-only ``P``)."""
    rng = np.random.default_rng(2)
    layout = _layout()
    mark = frozen if read_only else (lambda a: a)
    blocks, a, b_rows = (mark(rng.normal(size=(3, 2, 4))), mark(rng.normal(size=(5, 12))),
                         mark(rng.normal(size=(4, 12))))  # fmt: skip
    row_weights = mark(rng.uniform(0.1, 2.0, 4))
    residuals = (
        Residual("blocks", 0.7, rng.normal(size=6), blocks=blocks),
        Residual("dense", 2.0, rng.normal(size=5), A=a),
        Residual("weighted", 1.3, rng.normal(size=4), A=b_rows, row_weights=row_weights),
        Residual("off", 0.0, rng.normal(size=5), A=rng.normal(size=(5, 12))),  # no weight
    )
    p_mat, c = objective(layout, residuals)
    p_ref, c_ref = np.zeros((12, 12)), np.zeros(12)
    for r in residuals:
        rows = r.dense(layout)
        w = np.ones(r.b.size) if r.row_weights is None else r.row_weights
        p_ref += 2.0 * r.weight * (rows * w[:, None]).T @ rows
        c_ref -= 2.0 * r.weight * (rows * w[:, None]).T @ r.b
    np.testing.assert_allclose(p_mat, p_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(c, c_ref, rtol=1e-12, atol=1e-12)
    assert p_mat.flags.writeable is not read_only
    # the cost at any z, from P and c, differs from the sum of squares by a constant
    cost = [
        sum(r.weight * np.sum((1.0 if r.row_weights is None else r.row_weights)
                              * r.value(layout, z) ** 2) for r in residuals)
        - (0.5 * z @ p_mat @ z + c @ z)
        for z in rng.normal(size=(3, 12))
    ]  # fmt: skip
    np.testing.assert_allclose(cost, cost[0], rtol=1e-10)


def test_merged_bounds_intersect_and_a_hard_bound_wins_a_conflict():
    layout = _layout()  # 12 variables
    soft = Bounds("soft", np.array([0, 1, 2, 3]), np.array([-1.0, -1.0, 0.5, 0.0]),
                  np.array([1.0, 1.0, 1.0, 0.0]))  # fmt: skip
    narrower = Bounds("narrower", np.array([0, 1]), -0.5, 0.5)  # a scalar for every entry
    hard = Bounds("hard", np.array([1, 2]), np.array([0.6, -0.2]), np.array([0.8, 0.1]),
                  hard=True)  # fmt: skip
    lower, upper, conflict = merge_bounds(layout, (hard, soft, narrower))
    # 0: both soft bounds; 1: the hard interval lies above [-0.5, 0.5] -> its closest point
    # 0.6; 2: [-0.2, 0.1] misses [0.5, 1] -> 0.1; 3: fixed at 0; the rest open
    np.testing.assert_array_equal(lower[:4], [-0.5, 0.6, 0.1, 0.0])
    np.testing.assert_array_equal(upper[:4], [0.5, 0.6, 0.1, 0.0])
    np.testing.assert_array_equal(conflict[:4], [False, True, True, False])
    assert np.all(np.isneginf(lower[4:])) and np.all(np.isposinf(upper[4:]))
    assert not conflict[4:].any()
    none = fixed_variables(layout, (soft, hard))
    assert not none.any() and not none.flags.writeable
    fixed = Bounds("s", layout.s_index(), 1.0, 1.0, fixed=True)
    np.testing.assert_array_equal(np.flatnonzero(fixed_variables(layout, (soft, fixed))),
                                  layout.s_index())  # fmt: skip


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


def test_merged_bounds_of_scalars_lists_and_arrays_equal_numpys():
    layout = DecisionLayout(3, np.array([0.0, 0.1]), np.array([0.1, 0.2]))
    rng = np.random.default_rng(6)
    soft = (
        Bounds("a", np.arange(8), -rng.uniform(1, 2, 8), rng.uniform(1, 2, 8)),
        Bounds("b", [0, 1, 2], -0.5, 0.7),
        Bounds("c", np.array([[3], [7]], dtype=np.int32), 0.0, np.array([1.0, 2.0])),
    )
    hard = Bounds("h", np.arange(3), np.array([-2.0, 0.8, -0.1]), np.array([2.0, 1.0, 0.1]),
                  hard=True)  # fmt: skip
    lo, up, conflict = merge_bounds(layout, (*soft, hard))
    ref_lo, ref_up = np.full(8, -np.inf), np.full(8, np.inf)
    for b in soft:
        idx = np.asarray(b.index).ravel()
        ref_lo[idx] = np.maximum(ref_lo[idx], b.lower)
        ref_up[idx] = np.minimum(ref_up[idx], b.upper)
    clash = np.array([False, True, False])  # [-0.5, 0.7] misses [0.8, 1]: its point 0.8
    ref_lo[:3], ref_up[:3] = np.maximum(ref_lo[:3], hard.lower), np.minimum(ref_up[:3], hard.upper)
    ref_lo[1] = ref_up[1] = 0.8
    assert np.array_equal(lo, ref_lo) and np.array_equal(up, ref_up)
    assert conflict.dtype == np.bool_ and np.array_equal(conflict, np.r_[clash, np.zeros(5, bool)])
    lo[:] = 0.0  # the caller's arrays: the next merge starts open again
    empty = merge_bounds(layout, ())
    assert np.all(empty[0] == -np.inf) and np.all(empty[1] == np.inf) and not empty[2].any()


def test_constant_rows_are_the_same_read_only_object():
    rows = Inequality("g", frozen(np.ones((2, 3))), frozen(np.zeros(2)), frozen(np.ones(2)))
    assert constant_rows(rows, rows)
    assert constant_rows((rows, rows), None) is False
    pair = (rows, Bounds("b", frozen(np.arange(2)), 0.0, 1.0))
    assert constant_rows(pair, pair)
    assert not constant_rows(rows, rows._replace())  # another object
    writable = rows._replace(lower=np.zeros(2))
    assert not constant_rows(writable, writable)
    assert not constant_rows(None, None)
    odd = (rows, [1, 2])  # not a residual, bounds or inequality
    assert not constant_rows(odd, odd)


def test_a_block_qp_reads_as_its_dense_qp():
    rng = np.random.default_rng(3)
    hessian, c_rows = rng.normal(size=(2, 3, 3)), rng.normal(size=(1, 6))
    lower, upper = -np.ones(7), np.ones(7)
    dense = BlockQP(hessian, np.arange(6.0), c_rows, lower, upper).dense()
    np.testing.assert_array_equal(dense.P, scipy.linalg.block_diag(*hessian))
    np.testing.assert_array_equal(dense.A, np.vstack([np.eye(6), c_rows]))
    np.testing.assert_array_equal(dense.c, np.arange(6.0))
    assert dense.lower is lower and dense.upper is upper


def test_a_problem_reads_as_its_first_levels_dense_qp_and_describes_itself():
    rng = np.random.default_rng(4)
    layout = _layout()
    first = Residual("track", 2.0, rng.normal(size=5), A=rng.normal(size=(5, 12)))
    second = Residual("posture", 0.5, rng.normal(size=12), A=np.eye(12))
    rows = Inequality("wall", rng.normal(size=(2, 12)), -np.ones(2), np.ones(2))
    box = Bounds("box", np.arange(12), -1.0, 1.0)
    lower, upper, conflict = merge_bounds(layout, (box,))
    problem = Problem(
        layout,
        (BuiltLevel("task", 1e-7, (first,)), BuiltLevel("rest", 1e-3, (second,))),
        (box,),
        (rows,),
        np.concatenate([lower, rows.lower]),
        np.concatenate([upper, rows.upper]),
        conflict,
    )
    p_mat, c = objective(layout, (first,))
    qp = problem.dense(0)
    np.testing.assert_array_equal(qp.P, p_mat)
    np.testing.assert_array_equal(qp.c, c)
    np.testing.assert_array_equal(qp.A, np.vstack([np.eye(12), rows.C]))
    np.testing.assert_array_equal(problem.general_rows()[0], rows.C)
    P, c_iter, A, lo, up = problem  # noqa: N806 - the formulas' names
    np.testing.assert_array_equal(P, p_mat)
    assert len(problem) == 5 and problem[3] is problem.lower
    np.testing.assert_array_equal(problem.objective(1)[0], 2.0 * 0.5 * np.eye(12))
    assert problem.describe().splitlines() == [
        "level 1 task (tolerance 1e-07)",
        "  term track: 5 rows, weight 2",
        "level 2 rest (tolerance 0.001)",
        "  term posture: 12 rows, weight 0.5",
        "limit box: bounds on 12 variables",
        "limit wall: 2 rows",
    ]


def test_a_level_needs_a_term_and_a_positive_tolerance():
    with pytest.raises(ParameterError, match="at least one term"):
        Level(())
    with pytest.raises(ParameterError, match="tolerance must be > 0"):
        Level((object(),), tolerance=0.0)
    with pytest.raises(ParameterError, match="tolerance must be > 0"):
        Level((object(),), tolerance=float("nan"))
