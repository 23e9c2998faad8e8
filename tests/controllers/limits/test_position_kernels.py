"""The compiled pass of the predicted position rows
(dqcontrol/controllers/limits/position_kernels.py) against a numpy selection of the rows a
state can reach and their bounds ``q_min - q_base``, ``q_max - q_base``."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.limits.position_kernels import (
    reachable_rows_into,
    states_and_terminal_into,
)


def _draw(seed: int, p: int, n: int):
    rng = np.random.default_rng(seed)
    q_min, q_max = -rng.uniform(0.8, 1.2, n), rng.uniform(0.8, 1.2, n)
    q_lin = rng.uniform(-1.1, 1.1, (p, n))
    q_base = q_lin + rng.normal(scale=0.05, size=(p, n))
    reach, extra = rng.uniform(0.0, 0.3, p), rng.uniform(0.0, 0.2, n)
    return q_lin, q_base, q_min, q_max, reach, extra


def _numpy_rows(q_lin, q_base, q_min, q_max, reach, extra):
    r = reach[:, None] + extra[None, :]
    keep = (q_lin + r >= q_max) | (q_lin - r <= q_min)
    lower = np.broadcast_to(q_min, q_lin.shape) - q_base
    upper = np.broadcast_to(q_max, q_lin.shape) - q_base
    return keep, lower[keep], upper[keep]


@pytest.mark.parametrize("seed", range(4))
def test_reachable_rows_are_numpys_selection(seed):
    args = _draw(seed, 5, 7)
    p, n = args[0].shape
    keep = np.zeros((p, n), dtype=np.bool_)
    lower, upper = np.full(p * n, np.nan), np.full(p * n, np.nan)
    count = reachable_rows_into(*args, keep, lower, upper)
    ref_keep, ref_lo, ref_up = _numpy_rows(*args)
    assert 0 < count < p * n  # some rows kept, some not
    assert count == ref_keep.sum() and np.array_equal(keep, ref_keep)
    assert np.array_equal(lower[:count], ref_lo) and np.array_equal(upper[:count], ref_up)
    assert np.isnan(lower[count:]).all()  # nothing written past the kept rows


@pytest.mark.parametrize("terminal", [True, False])
def test_states_and_terminal_rows_are_two_selections(terminal):
    q_lin, q_base, q_min, q_max, reach, extra = _draw(9, 4, 6)
    p, n = q_lin.shape
    q_lin[-1, 0] = q_max[0]  # the last state at a limit: a terminal row at least
    none = np.zeros(n)
    keep = np.zeros((p + 1, n), dtype=np.bool_)
    lower, upper = np.full((p + 1) * n, np.nan), np.full((p + 1) * n, np.nan)
    count, last = states_and_terminal_into(
        q_lin, q_base, q_min, q_max, reach, none, extra, terminal, keep, lower, upper
    )
    ref_keep, ref_lo, ref_up = _numpy_rows(q_lin, q_base, q_min, q_max, reach, none)
    assert count == ref_keep.sum() and np.array_equal(keep[:p], ref_keep)
    assert np.array_equal(lower[:count], ref_lo) and np.array_equal(upper[:count], ref_up)
    if not terminal:
        assert last == 0
        return
    end = _numpy_rows(q_lin[-1:], q_base[-1:], q_min, q_max, reach[-1:], extra)
    assert last == end[0].sum() > 0 and np.array_equal(keep[p], end[0][0])
    assert np.array_equal(lower[p * n : p * n + last], end[1])
    assert np.array_equal(upper[p * n : p * n + last], end[2])
