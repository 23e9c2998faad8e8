"""Lexicographic priority levels (docs/theory.md §7.4) against a reference that solves them
level by level with another solver (quadprog), and the guarantee that a lower level never
worsens a higher level's optimum beyond the stated tolerance, also as a seeded hypothesis
property. (The thesis's controllers with ``priority="strict"`` are tested in
tests/controllers/thesis/test_controller.py, with the helpers here.)"""

from __future__ import annotations

import numpy as np
import pytest
import quadprog
from controllers.terms.step_contexts import random_context
from hypothesis import given, settings
from hypothesis import strategies as st

from dqcontrol.controllers.backends import DaqpBackend, OsqpBackend
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.levels import build_problem, held_rows, level_qp, solve_levels
from dqcontrol.controllers.core.problem import Bounds, DecisionLayout, Inequality, Level, Residual
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.terms.term import Term


def quadprog_solve(p_mat, c, a, lo, up):
    """``min ½ zᵀ P z + cᵀ z`` s.t. ``lo ≤ A z ≤ up`` by quadprog (equal bounds as
    equalities)."""
    p_mat = p_mat + 1e-12 * np.eye(c.size)
    fl, fu = np.isfinite(lo), np.isfinite(up)
    eq = fl & fu & (lo == up)
    rows = [a[eq], a[fl & ~eq], -a[fu & ~eq]]
    rhs = [lo[eq], lo[fl & ~eq], -up[fu & ~eq]]
    return quadprog.solve_qp(p_mat, -c, np.vstack(rows).T, np.concatenate(rhs), int(eq.sum()))[0]


def level_cost(problem, k, z) -> float:
    """``Σ w ‖A z - b‖²`` of level ``k``."""
    return sum(
        r.weight * float(np.sum(r.value(problem.layout, z) ** 2))
        for r in problem.levels[k].residuals
    )


def reference_levels(problem, exact: bool = True) -> list[np.ndarray]:
    """Each level solved by quadprog with the levels above held at the reference's own
    optimum: their held rows equal to their values there (``exact``), or within the
    levels' tolerances."""
    held, out = [], []
    for k in range(len(problem.levels)):
        qp = level_qp(problem, k, held)
        z = quadprog_solve(qp.P, qp.c, qp.A, qp.lower, qp.upper)
        out.append(z)
        rows = held_rows(problem, k, z, exact=exact)
        if rows is not None:
            held.append(independent_rows(rows, z) if exact else rows)
    return out


def independent_rows(rows, z):
    """The equalities ``A z = A z_k`` through an orthonormal basis of the row space of
    ``A`` (quadprog needs independent rows; a level's rows may be dependent), each within
    1e-10 (quadprog finds an exact equality inconsistent with a limit that ``z_k`` meets
    only to rounding)."""
    _, sv, vt = np.linalg.svd(rows[0], full_matrices=False)
    basis = vt[sv > 1e-10 * sv[0]]
    value = basis @ z
    return basis, value - 1e-10, value + 1e-10


class RandomTerm(Term):
    """Random rows ``A z - b`` of a given rank (a rank below the variables leaves the lower
    levels freedom)."""

    def __init__(self, name, rows, rank, num_vars, rng, held=True):
        self.name = name
        basis = rng.normal(size=(rank, num_vars))
        self._a = rng.normal(size=(rows, rank)) @ basis
        self._b = rng.normal(size=rows)
        self.weight = float(rng.uniform(0.5, 2.0))
        self.held = held

    def residual(self, ctx):
        return Residual(self.name, self.weight, self._b, A=self._a, held=self.held)


class RandomLimits(Limit):
    """Box bounds containing 0, and general rows ``lo ≤ C z ≤ up`` containing 0."""

    name = "random"

    def __init__(self, num_vars, rows, rng):
        self._lo = -rng.uniform(0.2, 2.0, num_vars)
        self._up = rng.uniform(0.2, 2.0, num_vars)
        self._c = rng.normal(size=(rows, num_vars))
        self._clo = -rng.uniform(0.1, 1.0, rows)
        self._cup = rng.uniform(0.1, 1.0, rows)

    def rows(self, ctx):
        index = np.arange(self._lo.size)
        return (
            Bounds("box", index, self._lo, self._up),
            Inequality("general", self._c, self._clo, self._cup),
        )


def random_problem(seed: int):
    rng = np.random.default_rng(seed)
    layout = DecisionLayout(3, np.array([0.0, 0.1]), np.array([0.1, 0.1]))
    nv = layout.num_vars
    ctx = StepContext(None, None, layout, 0.01, np.zeros(3), np.zeros(3), 0.0, None,
                      None, None, None, None, None)  # fmt: skip
    tol = float(rng.choice([1e-7, 1e-5, 1e-3]))
    reg = RandomTerm("reg", nv, nv, nv, rng, held=False)
    reg.weight = 1e-6
    levels = (
        Level((RandomTerm("first", 3, 2, nv, rng), reg), tol, "first"),
        Level((RandomTerm("second", 4, 3, nv, rng), reg), tol, "second"),
        Level((RandomTerm("third", nv, nv, nv, rng),), tol, "third"),
    )
    return build_problem(ctx, levels, (RandomLimits(nv, 3, rng),))


def reference_level(problem, k, points, exact):
    """Level ``k`` by quadprog with the levels above held: each level's held rows equal to
    their values at the last level's solution (``exact``), or within the level's tolerance
    of their values at its own solution ``points[j]``."""
    held = []
    for j, z in enumerate(points):
        z = points[-1] if exact else z
        rows = held_rows(problem, j, z, exact=exact)
        if rows is not None:
            held.append(independent_rows(rows, z) if exact else rows)
    qp = level_qp(problem, k, held)
    return quadprog_solve(qp.P, qp.c, qp.A, qp.lower, qp.upper)


@pytest.mark.parametrize("backend", [DaqpBackend, OsqpBackend], ids=["daqp", "osqp"])
@pytest.mark.parametrize("seed", range(15))
def test_levels_match_a_level_by_level_reference(seed, backend):
    """Each level's optimum, given the levels above at our solutions, lies between the
    reference's with those levels held within their tolerances (the most freedom a lower
    level may have) and with them held exactly (what the solve tries first)."""
    problem = random_problem(seed)
    result = solve_levels(problem, backend())
    if backend is DaqpBackend:
        assert result.failed_level is None
    else:  # ADMM does not always converge on the narrow bands that hold a level
        assert result.failed_level != 0
    points = []
    for k, sol in enumerate(result.per_level):
        if not sol.ok:
            break
        ours = level_cost(problem, k, sol.x)
        low = level_cost(problem, k, reference_level(problem, k, points, exact=False))
        try:
            high = level_cost(problem, k, reference_level(problem, k, points, exact=True))
        except ValueError:  # no point holds every level above exactly: the bands apply
            high = low
        slack = 1e-6 * max(1.0, abs(low)) + 1e-9
        assert low - slack <= ours <= high + slack
        held = [r for j, z in enumerate(points) if (r := held_rows(problem, j, z)) is not None]
        qp = level_qp(problem, k, held)
        ax = qp.A @ sol.x
        assert np.all(ax >= qp.lower - 1e-7) and np.all(ax <= qp.upper + 1e-7)
        points.append(sol.x)


@pytest.mark.parametrize("seed", range(15))
def test_a_lower_level_never_worsens_a_higher_one(seed):
    """Every held row of level k stays within its tolerance of level k's optimum in every
    lower level's solution, so level k's cost moves by at most what that allows."""
    problem = random_problem(seed)
    result = solve_levels(problem, DaqpBackend())
    final = result.solution.x
    for k, sol in enumerate(result.per_level[:-1]):
        tol = problem.levels[k].tolerance
        for r in problem.levels[k].residuals:
            if not r.held:
                continue
            at_optimum = r.value(problem.layout, sol.x)
            at_final = r.value(problem.layout, final)
            assert np.max(np.abs(at_final - at_optimum)) <= tol * (1 + 1e-6) + 1e-9
            bound = 2.0 * np.linalg.norm(at_optimum) * np.sqrt(at_optimum.size) * tol
            bound += at_optimum.size * tol**2
            worse = np.sum(at_final**2) - np.sum(at_optimum**2)
            assert worse <= bound + 1e-9


def test_the_contexts_of_the_reference_helpers(lbr4p):
    """The helpers above take the context the controllers build (a smoke test of the test's
    own building blocks on a real context)."""
    ctx = random_context(lbr4p, 2, seed=0)
    assert ctx.layout.num_vars == 16


# ------------------------------------------------------------------ property (hypothesis, seeded)
# the lexicographic solve in the null space of the held rows on random problems: dependent
# rows, levels that leave no freedom, tight limits that put the optimum on a vertex


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
