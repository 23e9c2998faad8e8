"""The joint box (dqcontrol/controllers/limits/joint_box.py): its applied and predicted
bounds against an independent numpy computation of velocity ∩ position ∩ braking
(docs/theory.md §5), and boxes that share one values array."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.step_contexts import random_context

from dqcontrol.controllers.limits.acceleration import AccelerationLimit
from dqcontrol.controllers.limits.joint_box import JointBoxLimit
from dqcontrol.controllers.limits.scaling_range import ScalingRange


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
def test_joint_box_rows(lbr4p, seed, braking):
    ctx = random_context(lbr4p, 5, seed=seed)
    near_limits(ctx, seed)
    box, box_pred, _, _ = limits_of(ctx, braking)
    idx = ctx.layout.qd_index()
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


def test_joint_boxes_given_one_values_array_share_their_bounds(lbr4p):
    ctx = random_context(lbr4p, 3, seed=1)
    box = limits_of(ctx)[0]
    other = JointBoxLimit(ctx.layout, box.q_min, box.q_max, box.qd_max, True, predicted=True)
    other.values = box.values
    box.qd_max[2] = 0.25  # in place
    box.q_min = box.q_min - 0.1  # assigned: copied in
    assert other.qd_max[2] == 0.25
    np.testing.assert_array_equal(other.q_min, box.q_min)
