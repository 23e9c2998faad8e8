"""The acceleration limit (dqcontrol/controllers/limits/acceleration.py): the hard bound of
the first block and the coupling rows between blocks against numpy (docs/theory.md §4.2,
§5), and its compiled coupling steps bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.limits.test_joint_box import limits_of, near_limits
from controllers.terms.step_contexts import random_context

from dqcontrol.controllers.limits.acceleration import coupling_steps


@pytest.mark.parametrize("seed", range(6))
def test_acceleration_rows(lbr4p, seed):
    ctx = random_context(lbr4p, 5, seed=seed)
    near_limits(ctx, seed)
    accel = limits_of(ctx)[3]
    layout, n = ctx.layout, lbr4p.nq
    a = ctx.a_max
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


def test_compiled_coupling_steps_are_numpys():
    """The coupling steps ``±h_i a_max[i + 1]`` from a moving ``a_max``, bit for bit."""
    rng = np.random.default_rng(31)
    a_max = rng.uniform(0.5, 50.0, size=(6, 7))
    h = rng.uniform(0.01, 0.2, size=5)
    dv, neg_dv = coupling_steps(h, a_max)
    assert np.array_equal(dv, (h[:, None] * a_max[1:]).ravel())
    assert np.array_equal(neg_dv, -dv)
    steady = np.broadcast_to(a_max[0], (6, 7))  # a constant bound, as the controllers pass it
    assert np.array_equal(coupling_steps(h, steady)[0], (h[:, None] * steady[1:]).ravel())
