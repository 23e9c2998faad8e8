"""The collision limit's compiled rows (dqcontrol/controllers/limits/collision_rows.py,
docs/theory.md §10.2, §10.3): the damper rows against their definition written in numpy, and
the predicted rows' floors against a braked approach integrated in small steps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol.controllers.limits.collision_rows import damper_rows, predicted_rows

SAFETY_M = 0.02


def test_damper_rows_are_their_definition_written_in_numpy():
    """``∇dᵀ q̇_0 ≥ -k max(d - d_s, 0)``: one row per finite distance, the gradient on the
    columns of ``q̇_0``, keyed by its pair; a failed query (``-inf``) gives none."""
    rng = np.random.default_rng(14)
    pair = np.array([3, 0, 5, 2])
    distance = np.array([0.05, -np.inf, 0.012, 0.2])
    gradient = rng.normal(size=(4, 3))
    columns = np.array([4, 5, 6])
    c, lower, keys, closest = damper_rows(pair, distance, gradient, SAFETY_M, 2.5, columns, 9)
    finite = np.isfinite(distance)
    expected_c = np.zeros((3, 9))
    expected_c[:, 4:7] = gradient[finite]
    assert np.array_equal(c, expected_c)
    np.testing.assert_allclose(
        lower, -2.5 * np.maximum(distance[finite] - SAFETY_M, 0.0), rtol=1e-15, atol=0
    )
    assert keys.tolist() == [3, 5, 2] and closest == 0.012
    none = damper_rows(pair[:1], np.array([-math.inf]), gradient[:1], SAFETY_M, 2.5, columns, 9)
    assert none[0].shape == (0, 9) and none[1].size == 0 and none[3] == math.inf


def _braked_distance(now_m, approach, braking, t_s, steps=20000):
    """The distance at ``t_s`` of a pair closing at ``approach`` [m/s] whose closing rate is
    braked at ``braking`` [m/s²] until it stops, integrated in small steps."""
    dt = t_s / steps
    d, v = now_m, approach
    for _ in range(steps):
        v_next = max(v - braking * dt, 0.0)
        d -= 0.5 * (v + v_next) * dt
        v = v_next
    return d


@pytest.mark.parametrize("now_m", [0.05, 0.021, 0.015])
def test_predicted_floors_allow_only_the_approach_braking_cannot_avoid(now_m):
    """A pair at ``d(q)`` closing at 0.4 m/s: each state's floor is the safety distance, or
    where braking at the full bound (``Σ |∇d_k| a_k``) cannot keep the pair out, the
    distance braking reaches by that state's time; a pair not closing keeps
    ``min(d_s, d(q))``."""
    n, p, num_pairs = 3, 4, 2
    gradient_now = np.array([0.2, -0.1, 0.3])
    qd = np.array([-1.0, 0.5, -0.5])  # closing rate -∇dᵀ q̇ = 0.2 + 0.05 + 0.15 = 0.4 m/s
    a_max = np.array([2.0, 4.0, 1.0])  # braking Σ |∇d_k| a_k = 0.4 + 0.4 + 0.3 = 1.1 m/s²
    times = np.array([0.001, 0.1, 0.3, 1.0])
    state = np.array([0, 1, 2, 3, 4, 0, 4])
    pair = np.array([0, 0, 0, 0, 0, 1, 1])
    distance = np.array([now_m, 0.04, 0.04, 0.04, 0.04, 0.015, 0.03])
    gradient = np.vstack([gradient_now] + [gradient_now] * 4 + [-gradient_now] * 2)
    weights = np.tril(np.ones((p, p))) * 0.1
    q_lin = np.zeros((p, n))
    c, lower, keys, closest = predicted_rows(
        state, pair, distance, gradient, (weights, q_lin, q_lin.copy(), times),
        (qd, a_max, 1.0), SAFETY_M, num_pairs, n + 1, p * (n + 1),
    )  # fmt: skip
    floors = lower[:4] + 0.04  # the offset is zero: q̄ = q_base
    expected = [min(SAFETY_M, _braked_distance(now_m, 0.4, 1.1, t)) for t in times]
    np.testing.assert_allclose(floors, expected, rtol=0, atol=1e-9)
    if now_m - 0.4**2 / 2.2 >= SAFETY_M:  # braking stops the pair before d_s: d_s itself
        assert np.all(floors == SAFETY_M)
    else:
        assert floors[-1] < SAFETY_M
    # the second pair moves away (rate -0.4 m/s): it may not come closer than it is
    assert lower[4] + 0.03 == pytest.approx(min(SAFETY_M, 0.015))
    assert closest == min(now_m, 0.015) and keys.tolist()[:4] == [2, 4, 6, 8]
