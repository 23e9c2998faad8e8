"""Each term of the QP core against an independent numpy computation (docs/theory.md §7.3):
its residual rows, its cost, its fast path, its memory."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, objective
from dqcontrol.controllers.prediction.thesis import ThesisPrediction
from dqcontrol.controllers.terms.damping import DampingTerm
from dqcontrol.controllers.terms.scaling import ScalingTerm
from dqcontrol.controllers.terms.stall_damping import StallDampingTerm
from dqcontrol.controllers.terms.tracking import TrackingTerm
from dqcontrol.model import LBR4P_Q0


def random_context(robot, p: int, seed: int, with_scaling: bool = True) -> StepContext:
    """A context at random states near ``LBR4P_Q0`` with the robot's real kinematics and
    random targets (some of them on the other side of ``±x``)."""
    rng = np.random.default_rng(seed)
    n = robot.nq
    tau = np.linspace(0.0, 1.0, p) ** 2 if p > 1 else np.zeros(1)
    durations = np.append(np.diff(tau), np.diff(tau)[-1:]) if p > 1 else np.array([0.01])
    layout = DecisionLayout(n, tau, durations, with_scaling=with_scaling)
    q = LBR4P_Q0 + rng.uniform(-0.3, 0.3, n)
    q_lin = q + rng.uniform(-0.2, 0.2, (p, n))
    q_lin[0] = q
    xs, jacs = robot.poses_and_jacobians(q_lin)
    xd = xs + rng.normal(scale=0.05, size=xs.shape)
    xd[::2] *= -1.0  # the nearer of ±x must be taken
    flip = np.einsum("pk,pk->p", xs, xd) < 0
    xs = np.where(flip[:, None], -xs, xs)
    jacs = np.where(flip[:, None, None], -jacs, jacs)
    dxd = rng.normal(size=xs.shape)
    sigma_lin = np.sort(rng.uniform(0.0, 1.0, p))
    pred = (
        ThesisPrediction(layout, 0.01)
        .predict(q, 0.0)
        ._replace(q_lin=q_lin, q_base=q_lin, sigma_lin=sigma_lin, sigma_base=sigma_lin)
    )
    a_max = rng.uniform(2.0, 20.0, (p, n))
    return StepContext(
        robot, None, layout, 0.01, q, rng.uniform(-1, 1, n), 0.0, pred, xs, jacs, xd, dxd,
        a_max,
    )  # fmt: skip


def numpy_w(ctx: StepContext, gain: float) -> np.ndarray:
    """``w_i = dx_d/dσ + K (x_d - x̂_i)`` (docs/theory.md §4.2)."""
    return ctx.target_derivatives + gain * (ctx.targets - ctx.poses)


def split(layout: DecisionLayout, z: np.ndarray):
    blocks = z.reshape(layout.num_blocks, layout.block_size)
    n = layout.num_joints
    return blocks[:, :n], (blocks[:, n] if layout.with_scaling else None)


@pytest.mark.parametrize("p", [1, 4])
def test_tracking_rows_are_j_qd_minus_s_w(lbr4p, p):
    ctx = random_context(lbr4p, p, seed=p)
    term = TrackingTerm(gain_per_s=7.0, weight=2.5)
    res = term.residual(ctx)
    z = np.random.default_rng(0).normal(size=ctx.layout.num_vars)
    qd, s = split(ctx.layout, z)
    w = numpy_w(ctx, 7.0)
    expected = np.einsum("pkn,pn->pk", ctx.jacobians, qd) - s[:, None] * w
    np.testing.assert_allclose(res.value(ctx.layout, z), expected.ravel(), atol=1e-12)
    assert res.weight == 2.5 and res.name == "tracking"
    # the fast path: 2 λ1 G_iᵀ G_i added to each block
    hessian = np.ones((p, 8, 8))
    assert term.add_gram(ctx, hessian)
    g = np.concatenate([ctx.jacobians, -w[:, :, None]], axis=2)
    np.testing.assert_allclose(
        hessian, 1.0 + 2.0 * 2.5 * np.einsum("pki,pkj->pij", g, g), rtol=1e-13, atol=1e-13
    )
    # its cost as objective() reads it: ½ zᵀ P z + cᵀ z = λ1 ‖J qd - s w‖²
    p_mat, c = objective(ctx.layout, (res,))
    assert 0.5 * z @ p_mat @ z + c @ z == pytest.approx(2.5 * np.sum(expected**2), rel=1e-12)


def test_tracking_without_scaling_variables_asks_for_w(lbr4p):
    ctx = random_context(lbr4p, 3, seed=5, with_scaling=False)
    term = TrackingTerm(gain_per_s=4.0)
    res = term.residual(ctx)
    z = np.random.default_rng(1).normal(size=ctx.layout.num_vars)
    qd, _ = split(ctx.layout, z)
    expected = np.einsum("pkn,pn->pk", ctx.jacobians, qd) - numpy_w(ctx, 4.0)
    np.testing.assert_allclose(res.value(ctx.layout, z), expected.ravel(), atol=1e-12)
    assert not term.add_gram(ctx, np.zeros((3, 7, 7)))  # no fast path: b ≠ 0


def test_scaling_and_damping_rows(lbr4p):
    ctx = random_context(lbr4p, 5, seed=2)
    layout = ctx.layout
    z = np.random.default_rng(2).normal(size=layout.num_vars)
    qd, s = split(layout, z)
    scaling = ScalingTerm(layout, weight=1e-3).residual(ctx)
    np.testing.assert_allclose(scaling.value(layout, z), s - 1.0, atol=0)
    damping = DampingTerm(layout, 1e-6).residual(ctx)
    np.testing.assert_allclose(damping.value(layout, z), qd.ravel(), atol=0)
    both = DampingTerm(layout, 1e-6, include_scaling=True).residual(ctx)
    np.testing.assert_allclose(both.value(layout, z), z, atol=0)
    assert not damping.held and scaling.held
    # the three costs summed by objective(): λ2 Σ (1 - s)² + μ Σ ‖qd‖² (+ constant)
    p_mat, c = objective(layout, (scaling, damping))
    value = 0.5 * z @ p_mat @ z + c @ z
    expected = 1e-3 * np.sum((1.0 - s) ** 2) + 1e-6 * np.sum(qd**2) - 1e-3 * s.size
    assert value == pytest.approx(expected, rel=1e-12)


def numpy_stall_weights(s_applied: list[float], mu: float, s_stall: float, delay: int):
    """The stall damping's weight at each step from the applied ``s`` of the steps before
    (docs/theory.md §4.3), written out."""
    weights, below, last = [], 0, 1.0
    for s in s_applied:
        weights.append(mu * (1.0 - last / s_stall) if below >= delay and mu else 0.0)
        below = below + 1 if s < s_stall else 0
        last = s
    return weights


def test_stall_damping_memory_and_weight(lbr4p):
    ctx = random_context(lbr4p, 2, seed=3)
    layout = ctx.layout
    term = StallDampingTerm(layout, weight_max=1e-3, stall_scaling=0.05, delay_steps=3)
    rng = np.random.default_rng(4)
    s_seq = list(np.where(rng.random(60) < 0.7, rng.uniform(0.0, 0.05, 60), 0.5))
    expected = numpy_stall_weights(s_seq, 1e-3, 0.05, 3)
    assert any(w > 0 for w in expected) and any(w == 0 for w in expected)
    for s_now, want in zip(s_seq, expected, strict=True):
        term.prepare(ctx)
        assert term.weight == pytest.approx(want, abs=0)
        res = term.residual(ctx)
        assert res.weight == term.weight and not res.held
        z = rng.normal(size=layout.num_vars)
        np.testing.assert_allclose(res.value(layout, z), split(layout, z)[0].ravel(), atol=0)
        hessian = np.zeros((2, 8, 8))
        assert term.add_gram(ctx, hessian)
        expected_h = np.zeros((2, 8, 8))
        expected_h[:, np.arange(7), np.arange(7)] = 2.0 * want
        np.testing.assert_array_equal(hessian, expected_h)
        term.observe(None, s_now)
    term.reset()
    term.prepare(ctx)
    assert term.weight == 0.0 and term.stalled_steps == 0


def test_delay_in_steps():
    assert StallDampingTerm.delay_steps_for(0.5, 1e-3) == 500
    assert StallDampingTerm.delay_steps_for(0.5, 0.05) == 10
    assert StallDampingTerm.delay_steps_for(0.0, 0.05) == 0
