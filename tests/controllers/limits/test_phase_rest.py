"""The rest-to-rest rows (dqcontrol/controllers/limits/phase_rest.py) against independent
computations: ``∂q/∂σ`` against numpy's pseudo-inverse, the rows' value and slope against
``√(2 b (T_tot - σ))`` and its finite difference, the phase's end, and when they are posed."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.controllers.limits.phase_rest import PhaseRestLimit, phase_speed_per_joint
from dqcontrol.controllers.prediction.consistent import ConsistentPrediction, interval_breakpoints
from dqcontrol.model import PANDA_Q0

P, N, T = 6, 7, 0.01
TASK = SimpleNamespace(duration=1.0)  # the one task of every context


def _states(panda, seed: int):
    rng = np.random.default_rng(seed)
    qs = PANDA_Q0 + 0.3 * rng.normal(size=(P, N))
    _poses, jacobians = panda.fast.poses_and_jacobians(qs)
    return rng, jacobians


def test_the_joint_speed_per_phase_is_the_least_norm_solution(panda):
    rng, jacobians = _states(panda, 1)
    tangents = np.einsum("pkn,pn->pk", jacobians, rng.normal(size=(P, N)))
    reference = np.abs(np.einsum("pnk,pk->pn", np.linalg.pinv(jacobians), tangents))
    got = phase_speed_per_joint(jacobians, tangents)
    np.testing.assert_allclose(got, reference, rtol=1e-7, atol=1e-9 * reference.max())


def _layout():
    breaks = interval_breakpoints(P, 0.5, T)
    return ConsistentPrediction(breaks, N, T, 1.0, 0.0).layout


def _context(panda, sigma: float, sigma_lin: np.ndarray, seed: int = 2):
    rng, jacobians = _states(panda, seed)
    tangents = np.einsum("pkn,pn->pk", jacobians, rng.normal(size=(P, N)))
    return SimpleNamespace(
        trajectory=TASK, sigma=sigma, period_s=T,
        jacobians=jacobians, target_derivatives=tangents, a_max=np.full((P, N), 10.0),
        prediction=SimpleNamespace(sigma_lin=sigma_lin),
    )  # fmt: skip


def _phases(layout, sigma: float, s: np.ndarray) -> np.ndarray:
    """``σ_i`` at the start of each interval for the scalings ``s``."""
    durations = layout.durations_s
    return sigma + np.concatenate(([0.0], np.cumsum(durations * s)[:-1]))


def test_the_rows_are_the_braking_bound_and_its_tangent(panda):
    layout = _layout()
    limit = PhaseRestLimit(layout, 1.0, share=0.1)
    sigma, s_lin = 0.95, np.full(P, 0.05)
    sigma_lin = np.cumsum(layout.durations_s * s_lin) + sigma  # state i: end of interval i
    ctx = _context(panda, sigma, sigma_lin)
    rows = limit.rows(ctx)
    b = limit.decelerations(ctx)
    speed = phase_speed_per_joint(ctx.jacobians, ctx.target_derivatives)
    np.testing.assert_allclose(b, 0.1 * np.min(10.0 / speed, axis=1))
    keys = rows.keys[:-1]
    assert keys.size >= 3 and rows.keys[-1] == P
    starts = np.concatenate(([sigma], ctx.prediction.sigma_lin[:-1]))

    def value(s: np.ndarray) -> np.ndarray:  # C z for the scalings s (joint velocities 0)
        z = np.zeros(layout.num_vars)
        z[layout.s_index()] = s
        return rows.C @ z

    # at the linearisation point the bound is exactly √(2 b (T_tot - σ̄_i)) on s_i
    at = value(s_lin)
    bound = np.sqrt(2.0 * b[keys] * (1.0 - starts[keys]))
    np.testing.assert_allclose(rows.upper[:-1] - (at[:-1] - s_lin[keys]), bound, rtol=1e-12)
    # moving s_j (j < i) moves σ_i: the row's slope is the bound's derivative
    eps = 1e-7
    for i in keys[keys > 0]:
        bumped = s_lin.copy()
        bumped[0] += eps
        shift = layout.durations_s[0] * eps
        exact = np.sqrt(2.0 * b[i] * (1.0 - starts[i] - shift)) - np.sqrt(
            2.0 * b[i] * (1.0 - starts[i])
        )
        row = list(keys).index(i)
        assert value(bumped)[row] - at[row] == pytest.approx(-exact, rel=1e-4)
    # the last row: the phase at the end of the horizon stays within the task
    z = np.zeros(layout.num_vars)
    z[layout.s_index()] = 1.0
    assert rows.C[-1] @ z == pytest.approx(layout.durations_s.sum())
    assert rows.upper[-1] == pytest.approx(1.0 - sigma)


def test_no_rows_far_from_the_end_and_all_of_them_near_it(panda):
    layout = _layout()
    limit = PhaseRestLimit(layout, 1.0)
    lin = np.linspace(0.1, 0.5, P)
    assert limit.rows(_context(panda, 0.0, lin)) is None  # measures b once, far from the end
    ctx = _context(panda, 0.0, lin)
    assert limit.rows(ctx) is None
    near = limit.rows(_context(panda, 0.999, np.full(P, 1.0)))
    assert near is not None and list(near.keys) == [*range(P), P]


def test_a_discrete_phase_brakes_to_rest_exactly_at_the_end(panda):
    """The first row alone (exact: σ_0 is known), applied step after step, reaches
    ``σ = T_tot`` with ``s`` decreasing to 0 and never passes it."""
    layout = _layout()
    limit = PhaseRestLimit(layout, 1.0)
    sigma, s_prev, history = 0.9, 1.0, []
    for _ in range(200):
        rows = limit.rows(_context(panda, sigma, np.full(P, min(sigma + 0.01, 1.0))))
        first = rows.C[0, layout.s_index()[0]]
        s_now = min(s_prev, rows.upper[0] / first, rows.upper[-1] / layout.durations_s[0])
        history.append(s_now)
        sigma += T * s_now
        s_prev = s_now
    assert sigma == pytest.approx(1.0, abs=1e-12) and sigma <= 1.0 + 1e-12
    assert np.all(np.diff(history) <= 1e-12) and history[-1] == pytest.approx(0.0, abs=1e-9)
