"""The non-zero entries of stacked rows, put together from each part's own
(``stacked_entries``, ``Problem.general_entries``), against the entries of the rows
stacked first."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.linalg.entries import nonzero_entries, stacked_entries
from dqcontrol.controllers.linalg.gram import frozen


@pytest.mark.parametrize("seed", range(8))
def test_entries_from_the_parts_are_those_of_the_stacked_rows(seed):
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 8))
    parts = []
    for _ in range(count):
        rows = int(rng.integers(0, 9))  # a part may have no rows at all
        part = rng.standard_normal((rows, 11)) * (rng.random((rows, 11)) < 0.4)
        parts.append(frozen(part) if rng.random() < 0.5 else part)  # kept or not
    stacked = np.vstack(parts)
    for _ in range(2):  # the second time from what was kept
        got = stacked_entries(tuple(parts))
        assert np.array_equal(got, nonzero_entries(stacked))
        assert not got.flags.writeable
    assert stacked_entries(()).shape == (0, 3)
