"""A reduced level's unconstrained optimum checked over the rows near their bounds only
(``clear_unconstrained_level``) against the full reduced solve from an empty set
(``reduced_on_active_set``, no change allowed): the same verdict on every draw, and the
same optimum and level rows bit for bit where both accept it. The bounds are drawn at the
optimum's own row values, shifted by a few tolerances either way, so that rows sit just
inside, on and just beyond them."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.backends.active_set import SOLVED
from dqcontrol.controllers.backends.clear_rows import clear_unconstrained_level
from dqcontrol.controllers.backends.reduced_active_set import reduced_on_active_set
from dqcontrol.controllers.entries import nonzero_entries
from dqcontrol.controllers.null_space import null_space

NV, NC, TOL = 12, 9, 1e-9


def _level(rng: np.random.Generator):
    """A level's rows, the basis it moves in, the point and the problem's rows ``C``."""
    basis = null_space(rng.standard_normal((5, NV)))
    rows = rng.standard_normal((10, NV)) * (rng.random((10, NV)) < 0.6)
    general = rng.standard_normal((NC, NV)) * (rng.random((NC, NV)) < 0.4)
    general[0] = 0.0  # a row with no entries at all
    return nonzero_entries(rows), rng.standard_normal(10), basis, rng.standard_normal(NV), general


def _full(entries, b, scale, basis, point, general, lower, upper, settings):
    dim, size = basis.shape[1], basis.shape[1] + lower.size
    rows, y, duals = np.empty((b.size, dim + 1)), np.empty(dim), np.empty(size)
    out = reduced_on_active_set(
        entries, b, scale, basis, point, nonzero_entries(general), lower, upper,
        np.zeros(0, dtype=np.int64), np.zeros(0, dtype=bool), settings, rows,
        np.empty((size, dim)), np.empty(size), np.empty(size), y, duals,
    )  # fmt: skip
    return out[0] == SOLVED and out[3] == 0, y, rows


@pytest.mark.parametrize("seed", range(10))
def test_the_rows_near_their_bounds_decide_as_the_full_check(seed):
    rng = np.random.default_rng(300 + seed)
    entries, b, basis, point, general = _level(rng)
    scale = np.full(b.size, 2.0)
    settings = np.array([TOL, 1e-9, 0.0, 1e-12, 64.0])
    a = np.vstack([np.eye(NV), general])
    # the optimum with no row in the way: its row values in z
    wide = np.full(NV + NC, 1e6)
    _ok, y_free, _rows = _full(entries, b, scale, basis, point, general, -wide, wide, settings)
    values = a @ (point + basis @ y_free)
    verdicts = set()
    for _ in range(40):
        shift = rng.choice([-3.0, -1.0, -0.5, 0.0, 0.5, 1.0, 3.0], size=NV + NC) * TOL
        lower = np.where(rng.random(NV + NC) < 0.5, values + shift, -np.inf)
        upper = np.where(np.isfinite(lower), np.inf, values + shift)
        far = rng.random(NV + NC) < 0.6  # most rows far from their bounds
        lower[far], upper[far] = values[far] - 1.0, values[far] + 1.0
        ok, y, rows = _full(entries, b, scale, basis, point, general, lower, upper, settings)
        y_fast, rows_fast = np.empty_like(y), np.empty_like(rows)
        fast = clear_unconstrained_level(
            entries, b, scale, basis, point, nonzero_entries(general), lower, upper,
            settings, rows_fast, y_fast,
        )  # fmt: skip
        assert fast == ok
        assert np.array_equal(rows_fast, rows)
        if ok:
            assert np.array_equal(y_fast, y)
        verdicts.add(ok)
    assert verdicts == {True, False}, "the draws must hold and break rows"
