"""A reduced level solved from its parts (``DaqpBackend.solve_reduced``: the QP formed and
solved on the last active set in one compiled call) against the same backend given the
dense QP of the level: the same answer bit for bit, over solves that reuse the last
active set, mend it, or fall back to DAQP."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from controllers.core.test_levels_properties import _problem

from dqcontrol.controllers.backends.base import Backend
from dqcontrol.controllers.backends.daqp.backend import DaqpBackend
from dqcontrol.controllers.core.levels import solve_levels
from dqcontrol.controllers.core.problem import Residual
from dqcontrol.controllers.core.reduced import level_rows, objective_in_basis, reduced_objective
from dqcontrol.controllers.linalg.gram import frozen


class _DenseOnly(Backend):
    """A DAQP backend seen through the contract's dense defaults: every level as its dense
    QP (no ``solve_reduced``, no warm levels)."""

    name = "daqp"

    def __init__(self) -> None:
        self._inner = DaqpBackend()

    def solve(self, key, qp):
        return self._inner.solve(key, qp)

    def reset(self) -> None:
        self._inner.reset()


def _same(a, b) -> None:
    assert a.failed_level == b.failed_level
    assert len(a.per_level) == len(b.per_level)
    for x, y in zip(a.per_level, b.per_level, strict=True):
        assert (x.ok, x.status, x.iterations) == (y.ok, y.status, y.iterations)
        assert np.array_equal(x.x, y.x)
        assert (x.duals is None) == (y.duals is None)
        if x.duals is not None:
            assert np.array_equal(x.duals, y.duals)


@pytest.mark.parametrize("seed", range(12))
def test_solving_from_the_parts_gives_the_dense_answer_bit_for_bit(seed):
    # the same structure with loose and tight boxes in turn: the last active set is right
    # (a repeated problem), wrong (the other boxes: mended or handed to DAQP), or absent
    parts, dense = DaqpBackend(), _DenseOnly()
    calls = []
    solve_reduced = parts.solve_reduced

    def counted(key, qp):
        calls.append(key)
        return solve_reduced(key, qp)

    parts.solve_reduced = counted
    for tight in (False, False, True, True, False):
        problem = _problem(seed, 3, 3, (4, 3), tight)
        _same(solve_levels(problem, parts), solve_levels(problem, dense))
    assert calls, "the lower levels went through solve_reduced"


def test_level_rows_follow_changed_weights_and_writable_rows():
    rng = np.random.default_rng(3)
    point, basis = rng.normal(size=6), np.linalg.qr(rng.normal(size=(6, 4)))[0]
    rows = frozen(rng.normal(size=(3, 6)))
    first = (Residual("a", 1.0, rng.normal(size=3), A=rows),)
    again = (Residual("a", 2.0, first[0].b, A=rows),)  # the same rows, another weight
    for residuals in (first, again, first):
        got = objective_in_basis(level_rows(residuals), point, basis)
        dense = 2.0 * residuals[0].weight * (rows @ basis).T @ (rows @ basis)
        np.testing.assert_allclose(got.hessian, dense, rtol=1e-12)
    writable = rng.normal(size=(3, 6))
    live = (Residual("b", 1.0, rng.normal(size=3), A=writable),)
    before = reduced_objective(live, point, basis).hessian
    writable *= 2.0  # rows that may change are read again at every call
    np.testing.assert_allclose(reduced_objective(live, point, basis).hessian, 4.0 * before)


def test_level_rows_of_strided_blocks_are_their_dense_rows():
    # a term may give a view of wider blocks (the tracking term's rows without the s column)
    rng = np.random.default_rng(5)
    wide = rng.normal(size=(3, 4, 6))
    wide[np.abs(wide) < 0.5] = 0.0
    blocks = wide[:, :, :5]
    residual = Residual("view", 0.5, rng.normal(size=12), blocks=blocks)
    dense = np.zeros((12, 15))
    for i in range(3):
        dense[4 * i : 4 * i + 4, 5 * i : 5 * i + 5] = blocks[i]
    point, basis = rng.normal(size=15), np.linalg.qr(rng.normal(size=(15, 6)))[0]
    got = reduced_objective((residual,), point, basis)
    rows = dense @ basis
    np.testing.assert_allclose(got.hessian, 2.0 * 0.5 * rows.T @ rows, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(
        got.gradient, 2.0 * 0.5 * rows.T @ (dense @ point - residual.b), rtol=1e-12, atol=1e-14
    )


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
