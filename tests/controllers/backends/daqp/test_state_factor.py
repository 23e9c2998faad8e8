"""The first level's Hessian factorised in the predicted states, against the dense
Hessian it stands for: its solves, the optimum on an active set, where it declines, and the
objective of the path-following controller's first level in both forms."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from dqcontrol.controllers.backends.daqp.active_set import (
    SOLVED,
    dense_factor,
    solve_on_active_set,
)
from dqcontrol.controllers.backends.daqp.backend import PIVOT_SHARE, DaqpBackend, _factor
from dqcontrol.controllers.backends.daqp.state_factor import (
    state_backward,
    state_factor,
    state_forward,
    state_forward_rows,
)
from dqcontrol.controllers.core.objective import dense_hessian, level_objective, state_objective
from dqcontrol.controllers.core.problem import DenseQP, StateHessian
from dqcontrol.controllers.prediction.consistent import (
    ConsistentPrediction,
    interval_breakpoints,
)

N = 7
M = N + 1


def _model(lag_s: float = 0.0, p: int = 10, period_s: float = 1e-3) -> ConsistentPrediction:
    return ConsistentPrediction(interval_breakpoints(p, 1.0, period_s), N, period_s, 1.0, lag_s)


def _states(rng: np.random.Generator, model: ConsistentPrediction, damping: float) -> StateHessian:
    """Each state's Gram matrix of six rows (rank 6 of 8, as the path error's) and a
    damping on every variable."""
    p = model.layout.num_blocks
    rows = rng.normal(size=(p, 6, M))
    grams = 2e4 * np.einsum("iax,iay->ixy", rows, rows)
    own = np.tile(damping * np.eye(M), (p, 1, 1))
    return StateHessian(grams, model.weights, model.sigma_weights, own)


def _dense(states: StateHessian) -> np.ndarray:
    """``Tᵀ G T + Λ`` by dense products."""
    p = states.grams.shape[0]
    t = np.zeros((p * M, p * M))
    g = np.zeros((p * M, p * M))
    own = np.zeros((p * M, p * M))
    for i in range(p):
        g[i * M : (i + 1) * M, i * M : (i + 1) * M] = states.grams[i]
        own[i * M : (i + 1) * M, i * M : (i + 1) * M] = states.damping[i]
        for j in range(p):
            scale = np.r_[np.full(N, states.weights[i, j]), states.phase_weights[i, j]]
            t[i * M : (i + 1) * M, j * M : (j + 1) * M] = np.diag(scale)
    return t.T @ g @ t + own


def _factor_of(states: StateHessian) -> tuple:
    ok, factor = state_factor(
        states.grams, states.weights, states.phase_weights, states.damping, PIVOT_SHARE
    )
    assert ok
    return factor


@pytest.mark.parametrize(("seed", "damping"), [(0, 2e-6), (1, 1.0), (2, 2e-6)])
def test_solves_with_the_state_factor_are_solves_with_the_hessian(seed, damping):
    rng = np.random.default_rng(seed)
    states = _states(rng, _model(), damping)
    p_mat = _dense(states)
    blocks = _factor_of(states)[1:]
    b = rng.normal(size=p_mat.shape[0])
    half, x = np.empty_like(b), np.empty_like(b)
    state_forward(blocks, b, half)
    state_backward(blocks, half, x)
    # backward error of x as a solution of P x = b, against LAPACK's Cholesky solve's
    lapack = scipy.linalg.cho_solve(scipy.linalg.cho_factor(p_mat), b)

    def backward_error(v):
        return np.abs(p_mat @ v - b).max() / (np.abs(p_mat).max() * np.abs(v).max())

    assert backward_error(x) <= max(4.0 * backward_error(lapack), 1e-15)
    if damping == 1.0:  # well conditioned: the solutions themselves agree
        np.testing.assert_allclose(x, lapack, rtol=1e-10, atol=1e-12 * np.abs(lapack).max())
        # F Fᵀ = P: |F⁻¹ b|² = bᵀ P⁻¹ b
        assert half @ half == pytest.approx(b @ lapack, rel=1e-10)
    rows = rng.normal(size=(5, b.size))
    rows[:, :20] = 0.0
    yt = np.empty((b.size, 5))
    state_forward_rows(blocks, rows, yt)
    for r in range(5):
        one = np.empty_like(b)
        state_forward(blocks, rows[r], one)
        np.testing.assert_allclose(yt[:, r], one, rtol=1e-13, atol=1e-300)


def test_the_optimum_on_an_active_set_is_the_dense_factors():
    rng = np.random.default_rng(4)
    states = _states(rng, _model(p=6), 1e-2)
    p_mat = _dense(states)
    n = p_mat.shape[0]
    general = rng.normal(size=(8, n))
    qp = DenseQP(
        p_mat, 50.0 * rng.normal(size=n), np.vstack([np.eye(n), general]),
        np.r_[-np.ones(n), -np.ones(8)], np.r_[np.ones(n), np.ones(8)],
    )  # fmt: skip
    ref = DaqpBackend(reuse_active_set=False).solve("cold", qp)
    assert ref.ok and ref.duals is not None
    active = np.flatnonzero(ref.duals)
    assert active.size >= 3, "the draw must have active rows"
    at_upper = ref.duals[active] > 0.0
    dense = _factor(p_mat)
    assert dense is not None
    out = []
    for factor in (dense_factor(dense), _factor_of(states)):
        z, duals = np.empty(n), np.empty(qp.A.shape[0])
        status, *_ = solve_on_active_set(
            factor, qp.c, general, np.zeros((0, 3)), False, qp.lower, qp.upper, active,
            at_upper, 1e-9, 1e-9, 0, z, duals,
        )  # fmt: skip
        assert status == SOLVED
        out.append((z, duals))
    np.testing.assert_allclose(out[1][0], out[0][0], atol=1e-9)
    np.testing.assert_allclose(out[1][1], out[0][1], atol=1e-7 * np.abs(out[0][1]).max())
    np.testing.assert_allclose(out[1][0], ref.x, atol=1e-7)


def test_the_state_factor_declines_what_it_cannot_factorise():
    rng = np.random.default_rng(5)
    lagged = _states(rng, _model(lag_s=0.004), 2e-6)  # T⁻¹ is not bidiagonal behind a lag
    ok, _ = state_factor(
        lagged.grams, lagged.weights, lagged.phase_weights, lagged.damping, PIVOT_SHARE
    )
    assert not ok
    plain = _states(rng, _model(), 2e-6)
    for own in (np.zeros_like(plain.damping), -plain.damping):  # singular, indefinite
        ok, _ = state_factor(plain.grams, plain.weights, plain.phase_weights, own, PIVOT_SHARE)
        assert not ok


def test_the_path_level_in_the_states_is_the_dense_objective(lbr4p):
    """The path-following controller's first level: ``c`` and the Hessian of its state
    form against :func:`level_objective`'s."""
    from dqcontrol.controllers import PathFollowingController
    from dqcontrol.model import LBR4P_Q0
    from dqcontrol.trajectories import Circle

    ctrl = PathFollowingController(lbr4p, Circle(1.0), 0.001, acceleration_limit=10.0)
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    for _ in range(30):
        q = q + 0.001 * ctrl.step(q).qd_command
    problem = ctrl.last_problem()
    residuals = problem.levels[0].residuals
    split = state_objective(problem.layout, residuals)
    assert split is not None
    c, states = split
    p_ref, c_ref = level_objective(problem.layout, residuals)
    p_mat = dense_hessian(states)
    assert np.abs(p_mat - p_ref).max() <= 1e-13 * np.abs(p_ref).max()
    assert np.abs(c - c_ref).max() <= 1e-13 * np.abs(c_ref).max()
    assert np.abs(_dense(states) - p_ref).max() <= 1e-12 * np.abs(p_ref).max()
    # the mismatch check's rows of the first state: the dense rows' first six over the
    # first block, which is all they read
    path = residuals[0]
    first = path.dense(problem.layout)[:6]
    m = problem.layout.block_size
    assert np.array_equal(ctrl._first_rows(path), first[:, :m])
    assert not first[:, m:].any()
    # a level without state rows has no state form
    assert state_objective(problem.layout, problem.levels[2].residuals) is None


def test_a_level_behind_a_servo_lag_has_no_state_form():
    """Behind a lag a block enters the later states with changing weights: the level's
    objective is the dense one."""
    from dqcontrol.controllers.core.problem import Residual, StateRows

    rng = np.random.default_rng(6)
    for lag_s, expected in ((0.0, True), (0.004, False)):
        model = _model(lag_s=lag_s, p=4)
        p = model.layout.num_blocks
        rows = StateRows(rng.normal(size=(p, 6, M)), model.weights, model.sigma_weights)
        a = np.zeros((6 * p, p * M))  # the dense rows are not read by state_objective
        res = Residual("path", 1.0, rng.normal(size=6 * p), A=a, states=rows)
        damping = Residual("damping", 1e-6, np.zeros(p * M), blocks=np.tile(np.eye(M), (p, 1, 1)))
        assert (state_objective(model.layout, (res, damping)) is not None) == expected
