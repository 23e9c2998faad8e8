"""Lexicographic priority levels (docs/theory.md §7.4) against a reference that solves them
level by level with another solver (quadprog), and the guarantee that a lower level never
worsens a higher level's optimum beyond the stated tolerance; the thesis's controllers with
``priority="strict"``."""

from __future__ import annotations

import numpy as np
import pytest
import quadprog
from controllers.terms.test_terms import random_context

from dqcontrol.controllers import LocalController, PredictiveController
from dqcontrol.controllers.backends import DaqpBackend, OsqpBackend
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.levels import build_problem, held_rows, level_qp, solve_levels
from dqcontrol.controllers.core.problem import Bounds, DecisionLayout, Inequality, Level, Residual
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.terms.term import Term
from dqcontrol.model import LBR4P_Q0
from dqcontrol.trajectories import Circle

THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])


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


@pytest.mark.parametrize("cls", [LocalController, PredictiveController])
def test_strict_priority_of_the_thesis_controllers(lbr4p, cls):
    """``priority="strict"``: three levels (tracking ≻ scaling ≻ damping), the same limits;
    each level matches the level-by-level reference and the applied command keeps every
    bound."""
    kw = {"num_instants": 6} if cls is PredictiveController else {}
    ctrl = cls(lbr4p, Circle(1.0), 0.05, velocity_limits=THESIS_VEL, acceleration_limit=10.0,
               priority="strict", **kw)  # fmt: skip
    assert [lev.name for lev in ctrl.levels] == ["tracking", "scaling", "damping"]
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    for k in range(12):
        res = ctrl.step(q)
        assert not res.diagnostics.fallback
        problem = ctrl.last_problem()
        n = lbr4p.nq
        assert np.all(res.qd_command >= problem.lower[:n]) and np.all(
            res.qd_command <= problem.upper[:n]
        )
        if k % 4 == 3:
            result = solve_levels(problem, DaqpBackend())
            reference = reference_levels(problem)
            for level, (sol, ref) in enumerate(zip(result.per_level, reference, strict=True)):
                ours, theirs = level_cost(problem, level, sol.x), level_cost(problem, level, ref)
                assert ours == pytest.approx(theirs, rel=1e-5, abs=1e-9)
        q = q + 0.05 * res.qd_command
    assert res.s < 1.0  # the 1 s circle is beyond the bounds: the scaling gives way


def test_strict_priority_needs_strictly_convex_levels(lbr4p):
    from dqcontrol.errors import ParameterError

    with pytest.raises(ParameterError, match="strict"):
        LocalController(lbr4p, Circle(1.0), 0.05, priority="strict", regularization=0.0)
    with pytest.raises(ParameterError, match="priority must be"):
        LocalController(lbr4p, Circle(1.0), 0.05, priority="lexicographic")


def test_the_contexts_of_the_reference_helpers(lbr4p):
    """The helpers above take the context the controllers build (a smoke test of the test's
    own building blocks on a real context)."""
    ctx = random_context(lbr4p, 2, seed=0)
    assert ctx.layout.num_vars == 16
