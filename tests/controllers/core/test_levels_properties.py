"""Property (hypothesis, seeded): the lexicographic solve in the null space of the held rows
on random problems — dependent rows, levels that leave no freedom, tight limits that put
the optimum on a vertex — against quadprog level by level (docs/theory.md §7.4)."""

from __future__ import annotations

import numpy as np
from controllers.core.test_levels import (
    RandomLimits,
    RandomTerm,
    level_cost,
    reference_level,
)
from hypothesis import given, settings
from hypothesis import strategies as st

from dqcontrol.controllers.backends import DaqpBackend
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.levels import build_problem, held_rows, level_qp, solve_levels
from dqcontrol.controllers.core.problem import DecisionLayout, Level


def _problem(seed: int, joints: int, blocks: int, ranks: tuple[int, ...], tight: bool):
    """Two levels of random rows with the given ranks (some rows repeat others of the
    level) and a non-held regularisation, a third of full rank, and limits containing 0
    (``tight``: boxes a hundred times narrower, so that many bounds are active at the
    optimum)."""
    rng = np.random.default_rng(seed)
    durations = np.full(blocks, 0.1)
    layout = DecisionLayout(joints, np.arange(blocks) * 0.1, durations)
    nv = layout.num_vars
    ctx = StepContext(None, None, layout, 0.01, np.zeros(joints), np.zeros(joints), 0.0,
                      None, None, None, None, None, None)  # fmt: skip
    reg = RandomTerm("reg", nv, nv, nv, rng, held=False)
    reg.weight = 1e-6
    levels = []
    for k, rank in enumerate(ranks):
        rank = min(rank, nv)
        rows = rank + int(rng.integers(0, 3))  # some rows repeat others
        levels.append(Level((RandomTerm(f"l{k}", rows, rank, nv, rng), reg), 1e-6, f"l{k}"))
    levels.append(Level((RandomTerm("last", nv, nv, nv, rng),), 1e-6, "last"))
    limits = RandomLimits(nv, int(rng.integers(0, 4)), rng)
    if tight:
        limits._lo *= 0.01
        limits._up *= 0.01
    return build_problem(ctx, tuple(levels), (limits,))


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    joints=st.integers(1, 4),
    blocks=st.integers(1, 3),
    ranks=st.tuples(st.integers(1, 6), st.integers(1, 6)),
    tight=st.booleans(),
)
def test_the_levels_are_solved_in_order_and_hold_the_levels_above(
    seed, joints, blocks, ranks, tight
):
    problem = _problem(seed, joints, blocks, ranks, tight)
    result = solve_levels(problem, DaqpBackend())
    assert result.failed_level is None, [s.status for s in result.per_level]
    points = []
    for k, sol in enumerate(result.per_level):
        z = sol.x
        # the limits, and every level above held (exactly, or within its band)
        qp = level_qp(problem, k, [])
        az = qp.A @ z
        assert np.all(az >= qp.lower - 1e-7) and np.all(az <= qp.upper + 1e-7)
        for j, zj in enumerate(points):
            rows = held_rows(problem, j, zj)
            if rows is not None:
                value = rows[0] @ z
                assert np.all(value >= rows[1] - 1e-7) and np.all(value <= rows[2] + 1e-7)
        # the level's optimum, given the levels above at our solutions: between quadprog's
        # with them within their bands and with them held exactly
        ours = level_cost(problem, k, z)
        low = level_cost(problem, k, reference_level(problem, k, points, exact=False))
        try:
            high = level_cost(problem, k, reference_level(problem, k, points, exact=True))
        except ValueError:  # no point holds every level above exactly: the bands apply
            high = low
        slack = 1e-6 * max(1.0, abs(low), abs(high)) + 1e-9
        assert low - slack <= ours <= high + slack
        points.append(z)
