"""A reduced level solved on a guessed set and checked over the rows near their bounds
only (``clear_level``) against the full reduced solve from the same set
(``reduced_on_active_set``, no change allowed): the same verdict on every draw, and the
same optimum, multipliers and level rows bit for bit where both accept it. The bounds are
drawn at the unconstrained optimum's own row values, shifted by a few tolerances either
way, so that rows sit just inside, on and just beyond them; the sets are empty, the true
ones (found by the full solve with mending) and wrong ones."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.backends.daqp.active_set import SOLVED
from dqcontrol.controllers.backends.daqp.clear_rows import clear_level, row_starts
from dqcontrol.controllers.backends.daqp.reduced_active_set import reduced_on_active_set
from dqcontrol.controllers.linalg.entries import nonzero_entries
from dqcontrol.controllers.linalg.null_space import null_space

NV, NC, TOL = 12, 9, 1e-9


def _level(rng: np.random.Generator):
    """A level's rows, the basis it moves in, the point and the problem's rows ``C``."""
    basis = null_space(rng.standard_normal((5, NV)))
    rows = rng.standard_normal((10, NV)) * (rng.random((10, NV)) < 0.6)
    general = rng.standard_normal((NC, NV)) * (rng.random((NC, NV)) < 0.4)
    general[0] = 0.0  # a row with no entries at all
    return nonzero_entries(rows), rng.standard_normal(10), basis, rng.standard_normal(NV), general


def _full(level, bounds, active, at_upper, changes: int):
    """``reduced_on_active_set`` from the set: (solved unchanged, y, duals, rows, set)."""
    entries, b, scale, basis, point, general = level
    lower, upper = bounds
    dim, size = basis.shape[1], basis.shape[1] + lower.size
    rows, y, duals = np.empty((b.size, dim + 1)), np.empty(dim), np.empty(size)
    settings = np.array([TOL, 1e-9, float(changes), 1e-12, 64.0])
    status, active, at_upper, count, _h, _g = reduced_on_active_set(
        entries, b, scale, basis, point, nonzero_entries(general), lower, upper,
        active, at_upper, settings, rows, np.empty((size, dim)), np.empty(size),
        np.empty(size), y, duals,
    )  # fmt: skip
    return status == SOLVED and count == 0, y, duals, rows, (active, at_upper)


def _fast(level, bounds, active, at_upper):
    entries, b, scale, basis, point, general = level
    lower, upper = bounds
    dim = basis.shape[1]
    rows, y, duals = np.empty((b.size, dim + 1)), np.empty(dim), np.empty(dim + lower.size)
    settings = np.array([TOL, 1e-9, 0.0, 1e-12, 64.0])
    general_entries = nonzero_entries(general)
    starts = row_starts(general_entries, general.shape[0])
    ok = clear_level(
        entries, b, scale, basis, point, general_entries, starts, lower, upper, active,
        at_upper, settings, rows, y, duals,
    )  # fmt: skip
    return ok, y, duals, rows


@pytest.mark.parametrize("seed", range(10))
def test_the_rows_near_their_bounds_decide_as_the_full_check(seed):
    rng = np.random.default_rng(300 + seed)
    entries, b, basis, point, general = _level(rng)
    level = (entries, b, np.full(b.size, 2.0), basis, point, general)
    none = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=bool))
    wide = np.full(NV + NC, 1e6)
    y_free = _full(level, (-wide, wide), *none, 0)[1]
    values = np.vstack([np.eye(NV), general]) @ (point + basis @ y_free)
    dim = basis.shape[1]
    verdicts = set()
    for _ in range(40):
        shift = rng.choice([-3.0, -1.0, -0.5, 0.0, 0.5, 1.0, 3.0], size=NV + NC) * TOL
        shift += rng.choice([0.0, -0.3], size=NV + NC)  # some bounds well inside: active
        lower = np.where(rng.random(NV + NC) < 0.5, values + shift, -np.inf)
        upper = np.where(np.isfinite(lower), np.inf, values - shift)
        far = rng.random(NV + NC) < 0.6  # most rows far from their bounds
        lower[far], upper[far] = values[far] - 1.0, values[far] + 1.0
        bounds = (lower, upper)
        true_set = _full(level, bounds, *none, 6)[4]
        wrong = (
            np.append(true_set[0], dim + int(rng.integers(NV + NC))),
            np.append(true_set[1], True),
        )
        for active, at_upper in (none, true_set, wrong):
            if len(set(active.tolist())) < active.size:
                continue  # a row twice: not a set
            ok, y, duals, rows, _set = _full(level, bounds, active, at_upper, 0)
            fast, y_fast, duals_fast, rows_fast = _fast(level, bounds, active, at_upper)
            assert fast == ok
            assert np.array_equal(rows_fast, rows)
            if ok:
                assert np.array_equal(y_fast, y)
                assert np.array_equal(duals_fast, duals)
            verdicts.add((active.size > 0, ok))
    assert {(False, True), (False, False), (True, True), (True, False)} <= verdicts
