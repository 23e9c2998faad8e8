"""A reduced level solved from its parts (``DaqpBackend.solve_reduced``: the QP formed and
solved on the last active set in one compiled call) against the same backend given the
dense QP of the level: the same answer bit for bit, over solves that reuse the last
active set, mend it, or fall back to DAQP."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.core.test_levels import _problem

from dqcontrol.controllers.backends.base import Backend
from dqcontrol.controllers.backends.daqp.backend import DaqpBackend
from dqcontrol.controllers.core.levels import solve_levels


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
