"""The torque limit (dqcontrol/controllers/limits/torque.py): its rows are the inverse
dynamics ``M (qd_i - qd_(i-1)) / h_i + C qd̄ + g`` at each block's start, linear in the
decision, against Pinocchio's RNEA (docs/theory.md §8.4)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.limits.torque import TorqueLimit
from dqcontrol.model import LBR4P_Q0


@pytest.mark.parametrize("first_step_s", [None, 0.03])
def test_the_rows_are_the_inverse_dynamics_at_each_block(lbr4p, first_step_s):
    rng = np.random.default_rng(21)
    p, n, period = 3, lbr4p.nq, 0.01
    layout = DecisionLayout(n, np.array([0.0, 0.05, 0.15]), np.array([0.05, 0.1, 0.1]))
    coupling = np.array([0.05, 0.1])
    effort = rng.uniform(50.0, 200.0, n)
    limit = TorqueLimit(layout, period, coupling, effort, 0.8, first_step_s)
    q = LBR4P_Q0 + rng.uniform(-0.3, 0.3, n)
    q_lin = q + rng.uniform(-0.1, 0.1, (p, n))
    plan = rng.uniform(-1.0, 1.0, (p, n))
    qd_now = rng.uniform(-1.0, 1.0, n)
    ctx = SimpleNamespace(
        robot=lbr4p, q=q, qd_now=qd_now,
        prediction=SimpleNamespace(q_lin=q_lin, warm_qd=plan),
    )  # fmt: skip
    rows = limit.rows(ctx)
    np.testing.assert_allclose(rows.upper - rows.lower, np.tile(2.0 * 0.8 * effort, p))
    z = rng.normal(size=layout.num_vars)
    qd = z.reshape(p, -1)[:, :n]
    steps = np.r_[period if first_step_s is None else first_step_s, coupling]
    starts, velocities = np.vstack([q, q_lin[:-1]]), np.vstack([qd_now, plan[1:]])
    before = np.vstack([qd_now, qd[:-1]])
    model, data = lbr4p.model, lbr4p.model.createData()
    tau = np.array([
        pin.rnea(model, data, starts[i], velocities[i], (qd[i] - before[i]) / steps[i])
        for i in range(p)
    ])  # fmt: skip
    # rows: lower ≤ C z ≤ upper ⇔ |τ(z)| ≤ f τ_max, with τ(z) = C z + shift
    shift = -0.8 * np.tile(effort, p) - rows.lower
    np.testing.assert_allclose(rows.C @ z + shift, tau.ravel(), rtol=1e-10, atol=1e-9)
