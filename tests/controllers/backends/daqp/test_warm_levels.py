"""The levels solved on their last active sets in one compiled call
(:mod:`dqcontrol.controllers.backends.daqp.warm_levels`, through ``DaqpBackend``) against
the same levels solved one by one: the same answer bit for bit at every outcome."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from controllers.backends.daqp.test_reduced_active_set import _same
from controllers.core.test_levels import _problem

from dqcontrol.controllers.backends.daqp.backend import DaqpBackend
from dqcontrol.controllers.core.levels import solve_levels


def _staircase(seed: int, tight: bool, ranks: tuple[int, int]):
    """:func:`_problem` with the first level's rows reaching the variables in steps (a
    predictive path level's profile, whose null space is compiled)."""
    problem = _problem(seed, 3, 4, ranks, tight)
    level = problem.levels[0]
    first = level.residuals[0]
    rows, nv = first.A.shape
    steps = np.arange(nv)[None, :] < 2 * np.arange(rows)[:, None] + 2
    staircase = first._replace(A=np.where(steps, first.A, 0.0))
    level = replace(level, residuals=(staircase, *level.residuals[1:]))
    return replace(problem, levels=(level, *problem.levels[1:]))


def test_the_levels_solved_in_one_call_are_those_solved_one_by_one(monkeypatch):
    # DaqpBackend solves every level on its last active set in one compiled call where it
    # can, and says where it stopped: each outcome (first level's set broken, a null
    # space for LAPACK, a lower level's set broken, all levels) must give the answer of
    # the levels solved one by one, bit for bit
    import dqcontrol.controllers.backends.daqp.backend as daqp

    outcomes = []
    kernel = daqp.warm_levels

    def counted(*args):
        out = kernel(*args)
        outcomes.append((out[0], len(args[2][0]) + 1, bool(out[6])))
        return out

    monkeypatch.setattr(daqp, "warm_levels", counted)
    kinds = (
        lambda seed, tight: _problem(seed, 3, 3, (4, 3), tight),  # dense rows: LAPACK's
        lambda seed, tight: _staircase(seed, tight, (8, 3)),  # then dense rows in the basis
        lambda seed, tight: _staircase(seed, tight, (12, 4)),  # every null space compiled
    )
    for seed in range(12):
        for make in kinds:
            fused, apart = DaqpBackend(), DaqpBackend()
            apart.solves_warm_levels = False  # the levels one by one
            for tight in (False, False, True, True, False, False):
                problem = make(seed, tight)
                _same(solve_levels(problem, fused), solve_levels(problem, apart))
    seen = set(outcomes)
    assert (3, 3, True) in seen, "every level in one call"
    assert (0, 3, False) in seen, "the first level's set broken"
    assert (1, 3, False) in seen, "the first null space left to LAPACK"
    assert (1, 3, True) in seen, "a lower level's set broken"
    assert (2, 3, False) in seen, "a lower level's null space left to LAPACK"
